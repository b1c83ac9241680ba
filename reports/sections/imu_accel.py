"""The ``imu.accelerometers`` block of results.json: K and b per temperature, tables, check.

Reads the accelerometer columns (``acc_x_g``…) of every completed static of
a mountings plan, fits the six-position calibration at each temperature
(``accel.py``), builds the same piecewise-linear and polynomial compensation
tables over temperature as the gyro matrix (leave-one-out residuals,
``analysis/thermal/compensation.py``) and a check table: the specific force the
compensation leaves on the calibration statics, per axis and temperature, in
sample and with that temperature left out of the table.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.analysis.imu.accel import (
    AccelFit,
    AccStatic,
    compensate_force,
    fit_all_accelerometers,
    static_mean,
)
from gyrocal.analysis.imu.mounted_steps import mounted_steps, unit_temp_c
from gyrocal.analysis.imu.table_check import Calibration, check_rows
from gyrocal.analysis.thermal import compensation as comp
from gyrocal.models.gravity import (
    NORMAL_GRAVITY_ANOMALY_MPS2,
    STANDARD_GRAVITY_MPS2,
    normal_gravity_mps2,
)
from gyrocal.models.imu_model import AXES
from gyrocal.record.plan_record import PlanRecord
from gyrocal.record.step_kind import StepKind

_ACC_COLUMNS = ("acc_x_g", "acc_y_g", "acc_z_g")
#: the flag columns a static's rows are judged by (the accelerometers' own status, the record's)
_FLAGS = ("acc_status", "status")
#: standard uncertainty assumed for a measured local gravity the station gives without one (m/s²)
MEASURED_GRAVITY_U_MPS2 = 1.0e-5


def local_gravity(plan: PlanRecord) -> tuple[float, float, str]:
    """(gravity in standard g, its relative standard uncertainty, how it was obtained)."""
    if plan.gravity_mps2 is not None:
        return (plan.gravity_mps2 / STANDARD_GRAVITY_MPS2, MEASURED_GRAVITY_U_MPS2 / plan.gravity_mps2,
                f"measured {plan.gravity_mps2:.6f} m/s² (station), u = 1 mGal assumed")
    latitude = plan.latitude_deg if plan.latitude_deg is not None else 0.0
    g = normal_gravity_mps2(latitude, plan.height_m)
    return (g / STANDARD_GRAVITY_MPS2, NORMAL_GRAVITY_ANOMALY_MPS2 / np.sqrt(3.0) / g,
            f"WGS-84 normal gravity at {latitude:g}° and {plan.height_m:g} m: {g:.6f} m/s² "
            "(NGA TR8350.2 eq. 4-1, 4-3); anomaly ±100 mGal, rectangular, as type B")


def read_statics(run_dir: Path, plan: PlanRecord, events: list[dict[str, Any]],
                 notes: list[str]) -> list[AccStatic]:
    """Every completed static of a mountings plan, reduced to three accelerometer means."""
    statics = []
    for logged in mounted_steps(run_dir, plan, events, StepKind.STATIC, _ACC_COLUMNS, notes,
                                "imu accelerometers: step {step_id} logged no acc_x_g…; left out",
                                flags=_FLAGS):
        samples, step = logged.samples, logged.step
        good = logged.good(_FLAGS)
        means = [static_mean(samples[c][good]) for c in _ACC_COLUMNS]
        statics.append(AccStatic(logged.step_id, step.temp_index, step.setpoint_c,
                                 unit_temp_c(samples, good),
                                 logged.mounting, np.array([m for m, _ in means]),
                                 np.array([u for _, u in means]), int(good.sum())))
    return statics


def _pairs(values: np.ndarray, scale: float) -> dict[str, float | None]:
    return {f"{AXES[i]}{AXES[j]}": (None if not np.isfinite(values[i, j]) else float(values[i, j] * scale))
            for i in range(3) for j in range(3) if i != j}


def _per_axis(values: np.ndarray, scale: float = 1.0) -> dict[str, float]:
    return {a: float(v * scale) for a, v in zip(AXES, values, strict=True)}


def _fit_json(fit: AccelFit) -> dict[str, Any]:
    return {
        "temp_index": fit.temp_index, "setpoint_c": fit.setpoint_c, "temp_c": fit.temp_c,
        "positions": [s.mounting.label for s in fit.statics], "dof": fit.dof,
        "birge_ratio": _per_axis(fit.birge_ratio),
        "sensitivity": fit.sensitivity.tolist(),
        "bias_mg": _per_axis(fit.bias_g, 1e3), "u_bias_mg": _per_axis(fit.u_bias_g, 1e3),
        "sf_error_ppm": _per_axis(fit.scale_factor - 1.0, 1e6),
        "u_sf_ppm": _per_axis(fit.u_scale_factor / np.abs(fit.scale_factor), 1e6),
        "u_sf_type_a_ppm": _per_axis(np.diag(fit.u_sensitivity_a) / np.abs(fit.scale_factor), 1e6),
        "misalignment_urad": _pairs(fit.misalignment_rad, 1e6),
        "u_misalignment_urad": _pairs(fit.u_misalignment_rad, 1e6),
    }


def _series(fits: list[AccelFit]) -> dict[str, list[list[float]]]:
    series: dict[str, list[list[float]]] = {}
    for fit in fits:
        m = fit.misalignment_rad * 1e6
        for i, axis in enumerate(AXES):
            series.setdefault(f"acc_bias_{axis}_mg", []).append([fit.temp_c, float(fit.bias_g[i] * 1e3)])
            series.setdefault(f"acc_sf_{axis}_ppm", []).append(
                [fit.temp_c, float((fit.scale_factor[i] - 1.0) * 1e6)])
            for j, other in enumerate(AXES):
                if i != j:
                    series.setdefault(f"acc_m_{axis}{other}_urad", []).append([fit.temp_c, float(m[i, j])])
    return series


def _check(fits: list[AccelFit]) -> list[dict[str, Any]]:
    """Residual specific force after compensation, per temperature and axis (µg)."""
    def residual(fit: AccelFit, cal: Calibration) -> np.ndarray:
        return np.array([compensate_force(cal[0], cal[1], s.mean_g) - fit.input_force_g(s)
                         for s in fit.statics]) * 1e6

    def summary(res: np.ndarray) -> dict[str, Any]:
        return {"rms_ug": _per_axis(np.sqrt(np.mean(res**2, axis=0))),
                "max_ug": _per_axis(np.max(np.abs(res), axis=0))}
    return check_rows(fits, lambda f: f.bias_g, residual, summary)


#: how the accelerometers' figures are defined (results.json ``imu.accelerometers.definitions``)
DEFINITIONS = {
    "bias_mg": "b_i, output-referred, mg (of 9.80665 m/s²)",
    "sf_error_ppm": "K_ii − 1: output g per g of specific force, ppm",
    "misalignment_urad": "M_ij = K_ij / K_ii (accelerometer i senses M_ij of the force along j)",
    "u_*": "standard uncertainty: type A (block means propagated, Birge-scaled) with the "
           "local gravity's type B in the scale factor",
    "check": "RMS specific-force residual on the calibration statics after compensation, µg",
}


@dataclass(frozen=True)
class AccelerometerResults:
    """results.json ``imu.accelerometers``: the fit per temperature against local gravity,
    the tables over temperature and the check."""

    gravity_g: float
    u_gravity_rel: float
    gravity_source: str
    fits: tuple[AccelFit, ...]
    #: quantity (acc_bias_x_mg…) → its points over temperature and tables
    compensation: Mapping[str, Mapping[str, Any]]
    check: tuple[Mapping[str, Any], ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "method": "IEEE Std 1293 static multi-position: each axis up and down at each "
                      "temperature",
            "gravity": {"g": self.gravity_g, "u_rel_ppm": self.u_gravity_rel * 1e6,
                        "source": self.gravity_source},
            "definitions": dict(DEFINITIONS),
            "temperatures": [_fit_json(f) for f in self.fits],
            "compensation": {k: dict(v) for k, v in self.compensation.items()},
            "check": [dict(row) for row in self.check],
        }


def accelerometer_section(run_dir: Path, plan: PlanRecord, events: list[dict[str, Any]],
                          notes: list[str]) -> AccelerometerResults | None:
    """``imu.accelerometers``, or None when no static logged accelerometers."""
    statics = read_statics(run_dir, plan, events, notes)
    if not statics:
        return None
    gravity_g, u_rel, how = local_gravity(plan)
    try:
        fits = fit_all_accelerometers(statics, gravity_g, u_rel)
    except ValueError as exc:
        notes.append(f"imu accelerometers: {exc}")
        return None
    if len(fits) < 3:
        notes.append(f"imu accelerometer compensation: {len(fits)} temperature(s); tables need ≥ 3")
    return AccelerometerResults(
        gravity_g, u_rel, how, tuple(fits),
        {name: {"points": points, "tables": comp.tables_json(points)}
         for name, points in _series(fits).items()},
        tuple(_check(fits)))
