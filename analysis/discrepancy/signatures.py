"""Linear designs and effect signatures, built from the model's own equation.

The refit and every effect's signature are computed by evaluating
:func:`gyrocal.models.indicated.indicated_rate` on the measured inputs with
one parameter switched on at a time, never by re-deriving the physics here:
the indicated rate is affine in every amplitude-like parameter (bias,
tempcos, SF error, effect amplitudes) once the shape parameters (τ,
threshold, frequency) are fixed, so "the model with parameter p = 1 minus the
model with every linear parameter at 0" is exactly p's regressor, including
the way thermal lag and the dead zone act through every other term.

Everything is input-referred and in deg/h: measured = gyro/scale_factor·3600.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from gyrocal.analysis.discrepancy.segments import Bins
from gyrocal.models.effects import EFFECTS
from gyrocal.models.gyro_model import EffectSpec, GyroModel
from gyrocal.models.indicated import ModelInputs, indicated_rate, input_history

#: The model's own parameters that are always refitted (the issue: bias, SF, tempcos).
BASE_KEYS = ("bias_dph", "bias_tempco_dph_per_c", "sf_error_ppm", "sf_tempco_ppm_per_c")

#: Effects that change the inputs of every other term (T_s, ω_t): adding one
#: changes the whole design, not just one column.
STRUCTURAL = ("thermal_lag", "dead_zone")

#: Effects judged elsewhere: the Markov term from the quiet-segment Allan
#: curve, periodic interference from the full-rate spectrum, quantization
#: (output stage, bounded angle error) not scored (see docs). The rate bandwidth and the
#: rate saturation have their own tests in the acceptance series (frequency response,
#: input-rate limits); a calibration's steady dwells inside the rate limits show neither.
NOT_IN_BIN_SEARCH = ("markov_bias", "periodic_interference", "quantization", "rate_bandwidth",
                     "rate_saturation")

#: Effects whose amplitude is fitted as a (cos, sin) pair, the phase following from it.
PHASED = {"table_angle_harmonic": ("amplitude_dph", "phase_deg")}
#: Threads that evaluate one design's models side by side (the machines here have 2 cores),
#: on logs long enough for that to pay (below it, thread start-up is most of the work).
EVAL_THREADS = 2
PARALLEL_MIN_SAMPLES = 1_000_000


@dataclass(frozen=True)
class Column:
    """One linear parameter of a design: a top-level key, or an effect's key.

    For a phased effect ``key`` is ``"cos"`` or ``"sin"`` (the quadrature pair).
    """

    effect: str | None
    key: str

    @property
    def label(self) -> str:
        return self.key if self.effect is None else f"{self.effect}.{self.key}"


def effect_columns(name: str) -> list[Column]:
    if name in PHASED:
        return [Column(name, "cos"), Column(name, "sin")]
    if name in NOT_IN_BIN_SEARCH:
        return []
    return [Column(name, k) for k in EFFECTS[name].linear_keys]


def model_columns(model: GyroModel) -> list[Column]:
    """Every linear parameter the refit adjusts for ``model``."""
    columns = [Column(None, k) for k in BASE_KEYS]
    for e in model.effects:
        columns.extend(effect_columns(e.name))
    return columns


def _set_effect(model: GyroModel, name: str, params: dict[str, float]) -> GyroModel:
    spec = model.effect(name)
    merged = dict(spec.params) if spec is not None else {}
    merged.update(params)
    effects = tuple(EffectSpec(e.name, merged) if e.name == name else e for e in model.effects)
    if spec is None:
        effects = (*effects, EffectSpec(name, merged))
    return replace(model, effects=effects)


def zero_linear(model: GyroModel) -> GyroModel:
    """The model with every refitted parameter at 0 (shape parameters and fixed terms kept)."""
    out = replace(model, **{k: 0.0 for k in BASE_KEYS})
    for e in model.effects:
        if e.name in PHASED:
            out = _set_effect(out, e.name, {PHASED[e.name][0]: 0.0})
        else:
            keys = [c.key for c in effect_columns(e.name)]
            if keys:
                out = _set_effect(out, e.name, {k: 0.0 for k in keys})
    return out


def unit_model(zeroed: GyroModel, column: Column) -> GyroModel:
    """``zeroed`` with ``column``'s parameter at 1 (its regressor is the difference)."""
    if column.effect is None:
        return replace(zeroed, **{column.key: 1.0})
    if column.effect in PHASED:
        amp, phase = PHASED[column.effect]
        return _set_effect(zeroed, column.effect, {amp: 1.0, phase: 0.0 if column.key == "cos" else 90.0})
    return _set_effect(zeroed, column.effect, {column.key: 1.0})


def apply_coefficients(model: GyroModel, columns: list[Column], coeffs: np.ndarray) -> GyroModel:
    """The model with fitted values; a (cos, sin) pair becomes amplitude and phase."""
    out = model
    pairs: dict[str, dict[str, float]] = {}
    for column, value in zip(columns, coeffs, strict=True):
        value = float(value)
        if column.effect is None:
            out = replace(out, **{column.key: value})
        elif column.effect in PHASED:
            pairs.setdefault(column.effect, {})[column.key] = value
        else:
            out = _set_effect(out, column.effect, {column.key: value})
    for name, pair in pairs.items():
        amp, phase = PHASED[name]
        c, s = pair.get("cos", 0.0), pair.get("sin", 0.0)
        out = _set_effect(out, name, {amp: math.hypot(c, s), phase: math.degrees(math.atan2(s, c))})
    return out


@dataclass(frozen=True)
class Design:
    """Binned offset and regressors of one model (deg/h), ready for whitening."""

    model: GyroModel            # the model the design is for (linear values irrelevant)
    columns: list[Column]
    offset_bins: np.ndarray     # ω_ind·3600 of the model with every linear parameter at 0
    x_bins: np.ndarray          # n_bins × len(columns)


class DesignBuilder:
    """Evaluates the equation on the measured inputs and bins the result."""

    #: Binned evaluations kept (each n_bins floats): a search refits the same structures often.
    CACHE_SIZE = 512

    def __init__(self, inputs: ModelInputs, bins: Bins) -> None:
        self.inputs = inputs
        self.bins = bins
        self.history = input_history(inputs)  # the same for every model: computed once
        self._binned: dict[str, np.ndarray] = {}

    def rate_dph(self, model: GyroModel) -> np.ndarray:
        """Full-rate noise-free indicated rate, deg/h (a new array: scaled in place, not copied)."""
        rate = indicated_rate(model, self.inputs, history=self.history).rate_dps
        rate *= 3600.0
        return rate

    def binned_rate_dph(self, model: GyroModel) -> np.ndarray:
        """Bin means of ``rate_dph(model)``, remembered by the model's value.

        A bin mean is linear, so a regressor's bins are the difference of two of
        these: the zeroed model's offset and the unit model's are each evaluated once
        per structure instead of once per fit (on 10 M samples an evaluation costs
        0.3 s, and the overnight analysis made about a hundred of them).
        """
        key = repr(model)
        hit = self._binned.get(key)
        if hit is None:
            hit = self._remember(key, self.bins.mean(self.rate_dph(model)))
        return hit

    def _remember(self, key: str, binned: np.ndarray) -> np.ndarray:
        if len(self._binned) >= self.CACHE_SIZE:
            self._binned.pop(next(iter(self._binned)))
        self._binned[key] = binned
        return binned

    def _columns(self, zeroed: GyroModel, columns: list[Column]) -> tuple[np.ndarray, np.ndarray]:
        units = [unit_model(zeroed, column) for column in columns]
        missing = [m for key, m in {repr(m): m for m in [zeroed, *units]}.items() if key not in self._binned]
        if len(missing) > 1 and len(self.inputs) >= PARALLEL_MIN_SAMPLES:
            # elementwise numpy releases the GIL: the evaluations of one design run side by side
            with ThreadPoolExecutor(EVAL_THREADS) as pool:
                evaluated = list(pool.map(lambda m: self.bins.mean(self.rate_dph(m)), missing))
            for m, binned in zip(missing, evaluated, strict=True):
                self._remember(repr(m), binned)
        offset = self.binned_rate_dph(zeroed)
        x = np.empty((self.bins.n_bins, len(columns)))
        for j, unit in enumerate(units):
            x[:, j] = self.binned_rate_dph(unit) - offset
        return offset, x

    def design(self, model: GyroModel) -> Design:
        columns = model_columns(model)
        offset, x = self._columns(zero_linear(model), columns)
        return Design(model, columns, offset, x)

    def extra_columns(self, model: GyroModel, spec: EffectSpec) -> tuple[list[Column], np.ndarray]:
        """Binned regressors of an additive effect (its shape parameters from ``spec``)."""
        columns = effect_columns(spec.name)
        return columns, self._columns(zero_linear(model.with_effect(spec)), columns)[1]


def placeholder_spec(name: str, shape: dict[str, float]) -> EffectSpec:
    """An effect with the given shape parameters and every amplitude at 0 (or 1 if 0 is out of range)."""
    params = {}
    for p in EFFECTS[name].params:
        if p.key in shape:
            params[p.key] = float(shape[p.key])
        elif p.kind == "linear":
            params[p.key] = 0.0
        else:
            params[p.key] = 1.0
    return EffectSpec(name, params)


@dataclass(frozen=True)
class SearchSpace:
    """What the inputs allow to be searched: record length, bin width, rate levels."""

    duration_s: float
    bin_width_s: float
    rate_levels_dps: tuple[float, ...]   # distinct |ω_t| held for a while, ascending, 0 first
    #: every distinct |ω_t| the table passed through (slews included), ascending: where a
    #: dead-zone threshold between two held levels can still be told apart
    passed_rates_dps: tuple[float, ...] = ()
    #: the log's sample period: the shortest thermal lag the model's per-sample filter resolves
    sample_period_s: float = 0.0


def rate_levels(table_rate_dps: np.ndarray, fs_hz: float, min_hold_s: float = 5.0) -> tuple[float, ...]:
    """Distinct |rate| levels held at least ``min_hold_s`` (dwells, not accelerations)."""
    magnitude = np.round(np.abs(np.asarray(table_rate_dps, dtype=float)), 6)
    values, counts = np.unique(magnitude, return_counts=True)
    held = values[counts >= min_hold_s * fs_hz]
    return tuple(sorted({0.0, *held.tolist()}))


#: Dead-zone thresholds tried per bracket of held levels before the refinement.
DEAD_ZONE_PER_BRACKET = 4


def passed_rates(table_rate_dps: np.ndarray, limit: int = 20000) -> tuple[float, ...]:
    """Distinct |rate| values of every sample, exactly, at most ``limit`` of them.

    Not rounded: a slew sample logged as 1.2999999999 and one at 1.3000000001
    fall on opposite sides of a 1.3 deg/s threshold, and rounding them together
    leaves a spike of ω·3600 deg/h wherever the two disagree.
    """
    values = np.unique(np.abs(np.asarray(table_rate_dps, dtype=float)))
    if values.size > limit:
        values = values[np.linspace(0, values.size - 1, limit).round().astype(int)]
    return tuple(values.tolist())


def dead_zone_candidates(threshold_dps: float, space: SearchSpace, most: int = 48) -> list[float]:
    """Thresholds that predict different data inside the bracket of held levels around one.

    Between two held levels only the slew samples tell thresholds apart: any two
    thresholds with no sample rate between them predict the same data, so the
    candidates are the midpoints between consecutive sample rates in the
    bracket (thinned to ``most``, evenly in rank).
    """
    levels = space.rate_levels_dps
    lo = max([v for v in levels if v < threshold_dps], default=0.0)
    hi = min([v for v in levels if v > threshold_dps], default=threshold_dps * 2.0)
    return _midpoints_between(lo, hi, space.passed_rates_dps, most)


def _midpoints_between(lo: float, hi: float, rates: tuple[float, ...], most: int) -> list[float]:
    inside = np.array([lo, *(r for r in rates if lo < r < hi), hi])
    mids = 0.5 * (inside[:-1] + inside[1:])
    if mids.size > most:
        mids = mids[np.linspace(0, mids.size - 1, most).round().astype(int)]
    return [float(m) for m in mids]


def dead_zone_neighbourhood(threshold_dps: float, tried: list[float], space: SearchSpace,
                            most: int = 48) -> list[float]:
    """Every distinguishable threshold between the two tried ones around ``threshold_dps``."""
    lo = max([v for v in tried if v < threshold_dps], default=0.0)
    hi = min([v for v in tried if v > threshold_dps], default=threshold_dps * 2.0)
    return _midpoints_between(lo, hi, space.passed_rates_dps, most)


#: The shortest thermal lag searched (s): the sensor's thermal time constant; below a second
#: the shift τ·dT/dt is under 0.1 °C even on a 5 °C/min ramp.
SHORTEST_LAG_S = 1.0
#: Spacing of the short lags (factor in τ): where the lag is only an amplitude (see below).
SHORT_LAG_STEP = 2.0


def short_lags(lo_tau: float, space: SearchSpace) -> list[float]:
    """Thermal lags below the bin-scaled grid, down to a second (or two samples), a factor 2 apart.

    The design evaluates the model per sample and bins the result, so a lag
    shorter than a bin is not averaged away: while τ is short against the
    ramps, T_s ≈ T_c − τ·dT/dt and every temperature term moves by τ times a
    fixed shape (the tempco through dT/dt on the bias, the SF tempco times ω
    wherever the table turns during a ramp). On a long log at 1–2 Hz the bins
    are tens of seconds wide and a clear lag can be far below the grid's
    3-bin start; the shortest lag tried then overshoots, its Δχ² is negative,
    and a probe takes the structure instead. On that
    amplitude-like stretch Δχ² ∝ 2k − k² in k = τ/τ_true, so a factor-2 grid
    keeps at least 0.83 of the peak for the bounded refinement to finish.
    """
    floor = max(SHORTEST_LAG_S, 2.0 * space.sample_period_s)
    out, tau = [], lo_tau / SHORT_LAG_STEP
    while tau >= floor:
        out.append(tau)
        tau /= SHORT_LAG_STEP
    return sorted(out)


def shape_grid(name: str, space: SearchSpace) -> list[dict[str, float]]:
    """Shape-parameter values to try for effect ``name`` (one empty dict if it has none).

    τ grids are log-spaced between a few bins and the record length; dead-zone
    thresholds are spread over each bracket of held rate levels by the slew
    samples inside it (without slews any threshold in a bracket predicts the
    same data and only the bracket is identifiable).
    """
    lo_tau = max(3.0 * space.bin_width_s, 10.0)
    if name == "thermal_lag":
        grid = np.geomspace(lo_tau, max(0.5 * space.duration_s, 2 * lo_tau), 14)
        return [{"tau_s": float(t)} for t in (*short_lags(lo_tau, space), *grid)]
    if name == "warmup_transient":
        # a transient that does not decay within the record is a drift: up to a third of the
        # record, beyond it bias_ramp is the simpler claim (a 10σ ramp was taken for a
        # warm-up of τ = 1.1 × the record)
        top = max(space.duration_s / 3.0, 2 * lo_tau)
        return [{"tau_s": float(t)} for t in np.geomspace(min(max(lo_tau, 30.0), top / 2), top, 14)]
    if name == "dead_zone":
        # a few thresholds inside each bracket of held levels (the slews tell them apart),
        # refined later over every distinguishable one (scoring.refine_shape)
        levels = space.rate_levels_dps[:7]
        return [{"threshold_dps": t} for a, b in zip(levels[:-1], levels[1:], strict=True)
                for t in _midpoints_between(a, b, space.passed_rates_dps, DEAD_ZONE_PER_BRACKET)]
    return [{}]


def _has_its_input(name: str, inputs: ModelInputs | None) -> bool:
    """An effect that reads an optional input column (``magnetic_sensitivity``: ``field_t``)
    is searched only when the log carries it, and ``thermal_lag`` only when the log has no
    measured sensor temperature: otherwise its signature is zero."""
    if name == "magnetic_sensitivity":
        return inputs is not None and inputs.field_t is not None
    if name == "thermal_lag":
        # a measured sensor temperature replaces the lagged chamber in the equation
        # (indicated.py): the lag's signature is zero and each τ tried a wasted refit
        return inputs is None or inputs.sensor_temp_c is None
    return True


def searched_effects(model: GyroModel, inputs: ModelInputs | None = None) -> list[str]:
    """Catalogue effects the bin-level search scores: not in the model, not judged elsewhere,
    and (given ``inputs``) with the input column they read present."""
    return [name for name in EFFECTS if not model.has_effect(name)
            and name not in NOT_IN_BIN_SEARCH and _has_its_input(name, inputs)]
