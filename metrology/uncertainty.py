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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from gyrocal.analysis.rate.dwell import Dwell
from gyrocal.analysis.rate.scale_factor import (
    ScaleFactorResult,
    analyze_scale_factor,
    fit_line,
    per_rate_sf,
)
from gyrocal.analysis.thermal import bias as bias_mod
from gyrocal.metrology.gum import (
    COVERAGE_PROBABILITY,
    Contribution,
    EvalType,
    Input,
    Uncertainty,
    propagate,
    rectangular,
)

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
    analysed = _memoised(lambda x: analyze_scale_factor(perturbed_dwells(means, x)))

    def figure(name: str):
        def f(x: dict[str, float]) -> float:
            r = analysed(x)
            return {"sf": r.sf, "bias": r.bias, "asymmetry_ppm": r.asymmetry_ppm,
                    "nonlinearity_rms_pct": r.nonlinearity_rms_pct,
                    "nonlinearity_max_ppm_fs": r.nonlinearity_max_ppm_fs}[name]
        return f

    found = {name: propagate(figure(name), inputs) for name in SWEEP_FIGURES}
    draws = nonlinearity_noise_draws(means, found["sf"].value)
    for name in NONLINEARITY_FIGURES:
        found[name] = _noise_bound(found[name], draws[name])
    return found


NONLINEARITY_FIGURES = ("nonlinearity_rms_pct", "nonlinearity_max_ppm_fs")
#: Draws of the nonlinearity noise bound (fixed seed: a report and its `verify` agree).
NOISE_BOUND_DRAWS = 20_000
NOISE_BOUND_SEED = 1


def nonlinearity_noise_draws(means: Sequence[MeanU], sf: float,
                             draws: int = NOISE_BOUND_DRAWS) -> dict[str, np.ndarray]:
    """Both nonlinearity figures of dwell means on an exact line, displaced by their noise.

    Each figure is a norm of a linear map of the dwell means: the residuals of the LS
    line (max |r| over full scale) and the per-rate SFs (their relative standard
    deviation). The maps are taken from the report's own functions (``fit_line``,
    ``per_rate_sf``) applied to unit vectors, so these draws are exactly what
    ``analyze_scale_factor`` would give for each sampled set of means (a test checks
    that against it), at a thousandth of the cost.
    """
    rates = np.array([m.rate_dps for m in means], dtype=float)
    n = rates.size
    eye = np.eye(n)
    residual_map = np.array([fit_line(rates, eye[i]).residuals for i in range(n)]).T
    temp_c = means[0].temp_c
    per_rate_map = np.array([list(per_rate_sf([Dwell(temp_c, r, float(eye[i][j]))
                                               for j, r in enumerate(rates)]).values())
                             for i in range(n)]).T
    rng = np.random.default_rng(NOISE_BOUND_SEED)
    # Normal draws at each dwell's u, not t_ν: sampling every mean as a t compounds the
    # tails across the dwells (the 95 % point of the largest of six |t_9| is 29 % beyond
    # that of six |z|), and the measured coverage was then 99.5 %; the six dwells' u are
    # independent estimates whose errors largely average out in the maximum.
    noise = np.column_stack([m.u * rng.standard_normal(draws) for m in means])
    residuals = noise @ residual_map.T
    full_scale = abs(sf) * float(np.max(np.abs(rates)))
    max_ppm_fs = np.max(np.abs(residuals), axis=1) / full_scale * 1e6
    by_rate = sf + noise @ per_rate_map.T
    if by_rate.shape[1] > 1:
        rms_pct = by_rate.std(axis=1, ddof=1) / by_rate.mean(axis=1) * 100.0
    else:
        rms_pct = np.zeros(draws)
    return {"nonlinearity_max_ppm_fs": max_ppm_fs, "nonlinearity_rms_pct": rms_pct}


def _noise_bound(linear: Uncertainty, values: np.ndarray) -> Uncertainty:
    """U of a nonlinearity figure from the noise it cannot tell from nonlinearity.

    Both figures are (semi)norms N of a linear map of the dwell means, so with the
    measured means = truth + noise, |N(truth + e) − N(truth)| ≤ N(e) (triangle
    inequality): the error of the estimate is bounded by the figure of the noise alone,
    whatever the true nonlinearity. U is the 95 % point of that bound, sampled by
    JCGM 101 (each mean displaced by its type A uncertainty). A linear
    propagation cannot do this - a norm is not smooth at zero, and with a true
    nonlinearity of 0 its estimate is biased upward by the noise (the linear U covered
    79 % where 95 % was claimed, and at a true 0 its linear u is 0). So u is the RMS of
    the bound, U its 95 % point and k = U/u; the budget has that one line (the table's
    rate scale error cancels: a common scale moves neither figure).
    """
    expanded = float(np.quantile(np.abs(values), COVERAGE_PROBABILITY))
    u = float(np.sqrt(np.mean(np.square(values))))
    if u <= 0.0 or not math.isfinite(expanded):
        return linear
    line = Contribution(
        "dwell-mean noise seen as nonlinearity (bound N(e), JCGM 101 sample)",
        "type A dwell means (batch-means standard errors), metrology/uncertainty.py",
        EvalType.A, "sampled", u, 1.0, u, math.inf)
    return Uncertainty(linear.value, u, math.inf, expanded / u, (line,))


T = TypeVar("T")


def _memoised(func: Callable[[dict[str, float]], T]) -> Callable[[dict[str, float]], T]:
    """``func`` evaluated once per distinct input point.

    Several figures are propagated from one analysis (SF, bias, asymmetry and the
    nonlinearities of one sweep; sensitivity and instability over temperature), and
    :func:`propagate` asks each of them for the same perturbed points: the analysis was
    repeated per figure (5 and 2 times over). The same inputs give the same result,
    so the figures are unchanged.
    """
    cache: dict[tuple[tuple[str, float], ...], T] = {}

    def call(x: dict[str, float]) -> T:
        key = tuple(x.items())
        if key not in cache:
            cache[key] = func(x)
        return cache[key]
    return call


def sf_temperature_uncertainty(means: Sequence[MeanU], type_b: TypeB,
                               reference_temp_c: float) -> dict[str, Uncertainty]:
    """u of the SF temperature sensitivity (ppm/°C) and instability (%) from all dwells."""
    temps = sorted({m.temp_c for m in means})
    inputs = mean_inputs(means) + [rate_input(type_b)] + [temp_input(t, type_b) for t in temps]
    # A dwell mean or a chamber temperature perturbs one temperature's sweep; the others
    # are analysed as at the central point, so each distinct sweep is analysed once.
    sweeps: dict[tuple[Dwell, ...], ScaleFactorResult] = {}

    def sweep(dwells: tuple[Dwell, ...]) -> ScaleFactorResult:
        if dwells not in sweeps:
            sweeps[dwells] = analyze_scale_factor(list(dwells))
        return sweeps[dwells]

    @_memoised
    def result(x: dict[str, float]) -> bias_mod.SfTemperature:
        dwells = perturbed_dwells(means, x)
        groups: dict[float, list[Dwell]] = {}
        for m, d in zip(means, dwells, strict=True):
            groups.setdefault(m.temp_c, []).append(d)
        return bias_mod.sf_temperature([sweep(tuple(groups[t])) for t in temps],
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


