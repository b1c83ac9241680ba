"""The ``imu`` section of results.json: matrices per temperature, compensation tables, check.

Only runs whose plan has ``mountings`` get it. It reads the three axis
columns of every completed dwell (``gyro_x``/``gyro_y``/``gyro_z``), trims
each to the whole revolutions the plan asked for, fits the matrix at each
temperature (``matrix.py``), builds piecewise-linear and polynomial tables
over temperature for every scale factor, misalignment element and bias (with
leave-one-out residuals, ``analysis/thermal/compensation.py``), and a check table:
what the compensation leaves on the calibration dwells, per axis and
temperature — in sample (the table at its own points) and leave-one-out (the
temperature's own point removed from the table, i.e. what it would leave at a
temperature it was not calibrated at).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.analysis.imu.matrix import ImuDwell, MatrixFit, compensate, fit_all
from gyrocal.analysis.imu.mounted_steps import mounted_steps, unit_temp_c
from gyrocal.analysis.imu.table_check import Calibration, check_rows
from gyrocal.analysis.rate.dwell import dwell_mean
from gyrocal.analysis.thermal import compensation as comp
from gyrocal.models.imu_model import AXES
from gyrocal.record.plan_record import PlanRecord
from gyrocal.record.step_kind import StepKind
from gyrocal.reports.sections.imu_accel import AccelerometerResults, accelerometer_section

_AXIS_COLUMNS = ("gyro_x", "gyro_y", "gyro_z")
#: the flag column a dwell's rows are judged by (the record's: the gyro marked the sample)
_FLAGS = ("status",)


def read_imu_dwells(run_dir: Path, plan: PlanRecord, events: list[dict[str, Any]],
                    notes: list[str]) -> list[ImuDwell]:
    """Every completed dwell of a mountings plan, reduced to three axis means."""
    fs_hz = plan.sample_rate_hz
    dwells = []
    for logged in mounted_steps(run_dir, plan, events, StepKind.DWELL, _AXIS_COLUMNS, notes,
                                "imu: step {step_id} has no three-axis columns; left out",
                                flags=_FLAGS):
        samples, step = logged.samples, logged.step
        good = logged.good(_FLAGS)
        turns = step.revolutions
        whole = int(turns) if turns and float(turns).is_integer() else "all"
        means = [dwell_mean(samples[c][good], fs_hz, 0.0, step.rate_dps,
                            revolutions=whole) for c in _AXIS_COLUMNS]
        dwells.append(ImuDwell(logged.step_id, step.temp_index, step.setpoint_c,
                               unit_temp_c(samples, good), logged.mounting, step.rate_dps,
                               np.array([m.mean for m in means]), means[0].n_samples))
    return dwells


def _matrix_json(values: np.ndarray, scale: float = 1.0) -> dict[str, float | None]:
    return {f"{AXES[i]}{AXES[j]}": (None if not np.isfinite(values[i, j]) else
                                    float(values[i, j] * scale))
            for i in range(3) for j in range(3) if i != j}


def _fit_json(fit: MatrixFit) -> dict[str, Any]:
    return {
        "temp_index": fit.temp_index,
        "setpoint_c": fit.setpoint_c,
        "temp_c": fit.temp_c,
        "dwells": len(fit.dwells),
        "dof": fit.dof,
        "sensitivity": fit.sensitivity.tolist(),
        "scale_factor": {a: float(v) for a, v in zip(AXES, fit.scale_factor, strict=True)},
        "u_scale_factor_ppm": {a: float(u / abs(s) * 1e6) for a, u, s in
                               zip(AXES, fit.u_scale_factor, fit.scale_factor, strict=True)},
        "misalignment_urad": _matrix_json(fit.misalignment_rad, 1e6),
        "u_misalignment_urad": _matrix_json(fit.u_misalignment_rad, 1e6),
        "bias_dph": {a: float(v) for a, v in zip(AXES, fit.bias_dph, strict=True)},
        "u_bias_dph": {a: float(v) for a, v in zip(AXES, fit.u_bias_dph, strict=True)},
        "axes": {AXES[a]: fit.axis_linearity(a) for a in range(3)},
    }


def _element_series(fits: list[MatrixFit]) -> dict[str, list[list[float]]]:
    """Every calibrated quantity over temperature: sf_x…, e_xy_urad…, bias_x_dph…"""
    series: dict[str, list[list[float]]] = {}
    for fit in fits:
        e = fit.misalignment_rad * 1e6
        for i, axis in enumerate(AXES):
            series.setdefault(f"sf_{axis}", []).append([fit.temp_c, float(fit.scale_factor[i])])
            series.setdefault(f"bias_{axis}_dph", []).append([fit.temp_c, float(fit.bias_dph[i])])
            for j, other in enumerate(AXES):
                if i != j:
                    series.setdefault(f"e_{axis}{other}_urad", []).append([fit.temp_c, float(e[i, j])])
    return series


def _check_table(fits: list[MatrixFit]) -> list[dict[str, Any]]:
    """Residual body rate after compensation, per temperature and axis (deg/h RMS)."""
    def residual(fit: MatrixFit, cal: Calibration) -> np.ndarray:
        return np.array([compensate(cal[0], cal[1], d.mean_xyz)
                         - d.mounting.up_vector() * (d.rate_dps + fit.earth_vertical_dps)
                         for d in fit.dwells]) * 3600.0

    def summary(res: np.ndarray) -> dict[str, Any]:
        return {"rms_dph": {a: float(np.sqrt(np.mean(res[:, i] ** 2))) for i, a in enumerate(AXES)},
                "max_dph": {a: float(np.max(np.abs(res[:, i]))) for i, a in enumerate(AXES)}}
    return check_rows(fits, lambda f: f.bias_output, residual, summary)


#: how the imu block's figures are defined (results.json ``imu.definitions``)
DEFINITIONS = {
    "sensitivity": "S_ij: output units per deg/s of body rate about axis j",
    "misalignment_urad": "E_ij = S_ij / S_ii (axis i senses E_ij of the rate about j)",
    "bias_dph": "S⁻¹·b, input-referred, vertical Earth rate removed",
    "u_*": "standard uncertainty, type A (least squares, dof given)",
    "check": "RMS body-rate residual on the calibration dwells after compensation",
}


@dataclass(frozen=True)
class ImuResults:
    """results.json ``imu``: the matrix per temperature, the tables over temperature, the
    check, the accelerometers. Without a fit (``fits`` None) only the (empty) tables, check and the
    accelerometers are stated."""

    accelerometers: AccelerometerResults | None
    fits: tuple[MatrixFit, ...] | None = None     # None: no fit was made
    mountings: Any = None                       # plan.json's, as recorded
    mounting_order: Any = None
    #: quantity (sf_x, e_xy_urad, bias_x_dph…) → its points over temperature and tables
    compensation: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    check: tuple[Mapping[str, Any], ...] = ()

    def to_json(self) -> dict[str, Any]:
        if self.fits is None:
            return {"temperatures": [], "compensation": {}, "check": [],
                    "accelerometers": self._accelerometers_json()}
        return {"mountings": self.mountings, "mounting_order": self.mounting_order,
                "definitions": dict(DEFINITIONS),
                "temperatures": [_fit_json(f) for f in self.fits],
                "compensation": {k: dict(v) for k, v in self.compensation.items()},
                "check": [dict(row) for row in self.check],
                "accelerometers": self._accelerometers_json()}

    def _accelerometers_json(self) -> dict[str, Any] | None:
        return None if self.accelerometers is None else self.accelerometers.to_json()


def imu_section(run_dir: Path, record: PlanRecord, events: list[dict[str, Any]],
                latitude_deg: float, notes: list[str]) -> ImuResults | None:
    """The ``imu`` block of results.json, or None for a single-axis plan."""
    if not record.mountings:
        return None
    accelerometers = accelerometer_section(run_dir, record, events, notes)
    dwells = read_imu_dwells(run_dir, record, events, notes)
    if not dwells:
        notes.append("imu: no completed three-axis dwell; no matrix")
        return ImuResults(accelerometers)
    try:
        fits = fit_all(dwells, latitude_deg)
    except ValueError as exc:
        notes.append(f"imu: {exc}")
        return ImuResults(accelerometers)
    series = _element_series(fits)
    if len(fits) < 3:
        notes.append(f"imu compensation: {len(fits)} temperature(s); tables need ≥ 3")
    return ImuResults(
        accelerometers, tuple(fits), record.raw.get("mountings"),
        record.raw.get("mounting_order"),
        {name: {"points": points, "tables": comp.tables_json(points)}
         for name, points in series.items()},
        tuple(_check_table(fits)))
