"""Uncertainty budgets of the calibrated quantities (GUM), from dwell means and the station.

Each measurement function here *is* the analysis code (scale_factor.py,
bias.py) called on perturbed inputs, so a budget can never describe a
different computation than the one that produced the reported value.

Inputs and where they come from:

* type A — every dwell and static-hold mean with its batch-means standard
  error (gum.batch_mean_sem: correlated gyro noise, not σ/√n) and ν = n_b − 1;
* type B — declared in the station's ``uncertainty`` section (rectangular
  half-widths; defaults in :data:`DEFAULT_TYPE_B`, reported as assumed when the
  station does not declare them): table rate accuracy (a common relative
  error of every commanded rate), chamber temperature accuracy (sensor +
  uniformity, per setpoint), latitude (Earth-rate removal) and input-axis tilt
  from vertical (couples the horizontal Earth rate into the bias).

The gyro's output resolution (LSB) is inside the type A scatter (the noise
dithers it) and is not counted twice. Correlations between quantities derived
from the same dwells are handled by computing each derived quantity (e.g. the
SF temperature sensitivity) from the dwell means directly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrocal.reports import bias as bias_mod
from gyrocal.reports.dwell import Dwell
from gyrocal.reports.gum import EvalType, Input, Uncertainty, propagate, rectangular
from gyrocal.reports.scale_factor import analyze_scale_factor

#: Station ``uncertainty`` keys (rectangular half-widths) and the values assumed without them.
DEFAULT_TYPE_B = {
    "table_rate_accuracy_ppm": 10.0,
    "chamber_temp_accuracy_c": 0.5,
    "latitude_accuracy_deg": 0.01,
    "axis_tilt_deg": 0.1,
}


@dataclass(frozen=True)
class TypeB:
    """The station's declared reference accuracies (± half-widths, rectangular)."""

    table_rate_accuracy_ppm: float
    chamber_temp_accuracy_c: float
    latitude_accuracy_deg: float
    axis_tilt_deg: float
    assumed: tuple[str, ...] = ()

    @classmethod
    def from_station(cls, declared: dict | None) -> TypeB:
        declared = declared or {}
        values = {k: float(declared.get(k, v)) for k, v in DEFAULT_TYPE_B.items()}
        return cls(**values, assumed=tuple(k for k in DEFAULT_TYPE_B if k not in declared))

    def to_json(self) -> dict:
        return {**{k: getattr(self, k) for k in DEFAULT_TYPE_B}, "distribution": "rectangular",
                "assumed_defaults": list(self.assumed)}


@dataclass(frozen=True)
class MeanU:
    """A dwell/hold mean with its type A standard uncertainty and dof."""

    temp_c: float
    rate_dps: float
    mean: float
    u: float
    dof: float
    step_id: str = ""


_RATE = "table rate scale error"


def rate_input(type_b: TypeB) -> Input:
    return Input(_RATE, 0.0, rectangular(type_b.table_rate_accuracy_ppm) * 1e-6, EvalType.B,
                 "station uncertainty.table_rate_accuracy_ppm", distribution="rectangular")


def temp_input(temp_c: float, type_b: TypeB) -> Input:
    return Input(f"chamber temperature error @{temp_c:g} °C", 0.0,
                 rectangular(type_b.chamber_temp_accuracy_c), EvalType.B,
                 "station uncertainty.chamber_temp_accuracy_c", distribution="rectangular")


def mean_inputs(means: Sequence[MeanU]) -> list[Input]:
    return [Input(_mean_name(m), m.mean, m.u, EvalType.A,
                  "dwell mean, batch-means standard error", m.dof) for m in means]


def _mean_name(m: MeanU) -> str:
    return f"mean {m.step_id or f'{m.rate_dps:+g} deg/s'} @{m.temp_c:g} °C"


def perturbed_dwells(means: Sequence[MeanU], x: dict[str, float]) -> list[Dwell]:
    scale = 1.0 + x.get(_RATE, 0.0)
    return [Dwell(m.temp_c + x.get(f"chamber temperature error @{m.temp_c:g} °C", 0.0),
                  m.rate_dps * scale, x[_mean_name(m)]) for m in means]


#: Figures of one temperature's sweep that get a budget.
SWEEP_FIGURES = ("sf", "bias", "asymmetry_ppm", "nonlinearity_rms_pct",
                 "nonlinearity_max_ppm_fs")


def sweep_uncertainty(means: Sequence[MeanU], type_b: TypeB) -> dict[str, Uncertainty]:
    """u of SF, LS bias (output units), asymmetry and nonlinearity at one temperature."""
    inputs = mean_inputs(means) + [rate_input(type_b)]

    def figure(name: str):
        def f(x: dict[str, float]) -> float:
            r = analyze_scale_factor(perturbed_dwells(means, x))
            return {"sf": r.sf, "bias": r.bias, "asymmetry_ppm": r.asymmetry_ppm,
                    "nonlinearity_rms_pct": r.nonlinearity_rms_pct,
                    "nonlinearity_max_ppm_fs": r.nonlinearity_max_ppm_fs}[name]
        return f

    return {name: propagate(figure(name), inputs) for name in SWEEP_FIGURES}


def sf_temperature_uncertainty(means: Sequence[MeanU], type_b: TypeB,
                               reference_temp_c: float) -> dict[str, Uncertainty]:
    """u of the SF temperature sensitivity (ppm/°C) and instability (%) from all dwells."""
    temps = sorted({m.temp_c for m in means})
    inputs = mean_inputs(means) + [rate_input(type_b)] + [temp_input(t, type_b) for t in temps]

    def result(x: dict[str, float]) -> bias_mod.SfTemperature:
        dwells = perturbed_dwells(means, x)
        groups: dict[float, list[Dwell]] = {}
        for m, d in zip(means, dwells, strict=True):
            groups.setdefault(m.temp_c, []).append(d)
        return bias_mod.sf_temperature([analyze_scale_factor(groups[t]) for t in temps],
                                       reference_temp_c)

    return {"sensitivity_ppm_per_c": propagate(lambda x: result(x).sensitivity_ppm_per_c, inputs),
            "instability_pct": propagate(lambda x: result(x).instability_pct, inputs)}


def _earth_inputs(latitude_deg: float, type_b: TypeB) -> list[Input]:
    return [Input("latitude", latitude_deg, rectangular(type_b.latitude_accuracy_deg), EvalType.B,
                  "station site.latitude_deg ± uncertainty.latitude_accuracy_deg",
                  distribution="rectangular"),
            Input("input-axis tilt from vertical", 0.0,
                  math.radians(rectangular(type_b.axis_tilt_deg)), EvalType.B,
                  "station uncertainty.axis_tilt_deg (horizontal Earth rate coupling)",
                  distribution="rectangular")]


def _earth_dph(x: dict[str, float], remove: bool) -> float:
    if not remove:
        return 0.0
    lat = math.radians(x["latitude"])
    tilt = x["input-axis tilt from vertical"]
    return bias_mod.EARTH_RATE_DPH * (math.sin(lat) * math.cos(tilt) + math.cos(lat) * tilt)


def bias_uncertainty_static(hold: MeanU, sf: Uncertainty, latitude_deg: float | None,
                            type_b: TypeB) -> Uncertainty:
    """u of bias (deg/h) = hold mean / SF(T) · 3600 − Earth rate."""
    remove = latitude_deg is not None
    inputs = mean_inputs([hold]) + [
        Input("scale factor", sf.value, sf.u, EvalType.A, "SF budget at this temperature",
              sf.dof_eff)] + _earth_inputs(latitude_deg or 0.0, type_b)
    return propagate(lambda x: x[_mean_name(hold)] / x["scale factor"] * 3600.0
                     - _earth_dph(x, remove), inputs)


def bias_uncertainty_sweep(means: Sequence[MeanU], latitude_deg: float | None,
                           type_b: TypeB) -> Uncertainty:
    """u of bias (deg/h) from the sweep's LS intercept when no static hold exists."""
    remove = latitude_deg is not None
    inputs = mean_inputs(means) + [rate_input(type_b)] + _earth_inputs(latitude_deg or 0.0,
                                                                          type_b)

    def f(x: dict[str, float]) -> float:
        r = analyze_scale_factor(perturbed_dwells(means, x))
        return r.bias / r.sf * 3600.0 - _earth_dph(x, remove)

    return propagate(f, inputs)


def slope_uncertainty(temps_c: Sequence[float], values: Sequence[Uncertainty],
                      type_b: TypeB, what: str) -> Uncertainty:
    """u of a least-squares slope over temperature (e.g. bias tempco, deg/h/°C)."""
    names = [f"{what} @{t:g} °C" for t in temps_c]
    inputs = [Input(n, v.value, v.u, EvalType.A, f"{what} budget", v.dof_eff)
              for n, v in zip(names, values, strict=True)]
    inputs += [temp_input(t, type_b) for t in temps_c]

    def f(x: dict[str, float]) -> float:
        t = np.array([tc + x[f"chamber temperature error @{tc:g} °C"] for tc in temps_c])
        return float(np.polyfit(t, np.array([x[n] for n in names]), 1)[0])

    return propagate(f, inputs)


def with_uncertainty(entry: dict, unc: Uncertainty) -> dict:
    """``entry`` with u, U, k, dof_eff and budget added beside its value (new keys only)."""
    return entry | unc.to_json()

