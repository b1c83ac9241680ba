"""Out-of-catalogue probes: generic shapes that compete with the catalogue before anything is named.

A catalogue effect is named only if nothing generic explains the data
clearly better; otherwise structure outside the catalogue would be named
after its nearest neighbour (a scale-factor step first drew thermal_lag and
sf_temp_quadratic at probability 1.0; a rate² acting on one rate sign drew
sf_nonlinearity_quadratic + sf_nonlinearity_cubic at 1.0; a bias accelerating
with time, or a ramp in |t − t0|, drew markov_bias at 1.0). The probes:

* a **bias step** at any of ``POSITIONS`` times (deg/h);
* a **scale-factor step** at any of those times (ppm: a rate-proportional
  change, ω·1e-6·ppm in deg/s);
* a **slow sinusoid** of unknown period, from half the record down to eight
  bins (a cos/sin pair per frequency, deg/h). At least two periods must be in
  the record: less is a bump, not a periodicity, and a bump is what two wiggles
  of a slow Gauss–Markov bias look like (a sinusoid of period 1.1 record lengths
  took the place of a τ = 1000 s Markov bias on a 1-hour record);
* a **cubic in time** (u, u², u³ with u the time from mid-record over half the
  record, deg/h each): a bias that accelerates or bends, beyond the catalogue's
  linear ramp and exponential warm-up;
* a **ramp in |t − t0|** (deg/h per hour) with t0 at any of ``ABS_RAMP_POSITIONS``
  interior times: a drift that turns round;
* a **rate² on one rate sign** (deg/h per (deg/s)², ω² for ω > 0 or for ω < 0):
  the catalogue's ω² and ω³ together only approximate it;
* a **bias by rate sign** (deg/h, +1 for ω > 0, −1 for ω < 0);
* two **terms in dT/dt** of the chamber: |dT/dt| (deg/h per °C/min, the same
  sign heating and cooling) and dT/dt·(T − T̄) (deg/h per °C·°C/min);
* a **bias cubic in temperature** (ΔT² and ΔT³ about the record's mean, deg/h
  per °C² and °C³), the next order beyond the catalogue's quadratic law: with
  its own quadratic, as the cubic in time has its own lower orders (a cubic law
  about any other temperature is a cubic and a quadratic about the mean; the
  cubic column alone left the quadratic part to a Markov bias at 1.0);
* a **scale factor drifting with time** (ppm per hour);
* a **decaying bias step** (deg/h): a jump at any of ``DECAY_POSITIONS`` times
  between 10 % and 90 % of the record that relaxes with any of ``DECAY_TAUS``
  time constants, H(t − t0)·e^(−(t − t0)/τ). A jump that relaxes (a mode hop, a
  thermal shock, a disturbance settling) is neither a step nor a stationary
  process: a bias step catches only its start and leaves the decay to a Markov
  bias (named at 1.0), and a dT/dt bias catches it where it meets a ramp. It
  starts after the record's start, where it would be the catalogue's
  warmup_transient.
* a **rate² with the rate's sign**, ω·|ω| (deg/h per (deg/s)²): an odd term the catalogue's
  ω³ only approximates (the one-sign rate² is this and the catalogue's ω² in equal parts);
* two **even rate terms growing with temperature**, |ω|·ΔT (deg/h per deg/s·degC) and
  ω²·ΔT (deg/h per (deg/s)²·degC), ΔT about the model's reference temperature as its
  tempco laws are: a bias in |ω|·ΔT and a rate² growing with temperature were named
  markov_bias at 0.8 and above, for want of a shape in rate and temperature together.
* a **bias by the sign of dT/dt** (deg/h, + heating, − cooling, zero in soaks), the same with
  **a level of its own for heating and for cooling** (two columns: the one-column sign shares a
  named temp_rate_bias's probability where every ramp has one |dT/dt| and the two cannot be told
  apart, the BIC charge of a second column would not), and a **bias
  in the table's angular acceleration** dω/dt (deg/h per deg/s², non-zero in slews only):
  shapes that live in transitions (transitions.py says what they took the place of).
* a **bias from table spin heating**: |ω| or ω² through a first-order memory of any of
  ``SPIN_TAUS`` time constants (log-spaced from three bins to a third of the record), deg/h
  per deg/s or per (deg/s)² once settled; and a **bias ∝ the net table turns** since the
  start, ∫ω dt (deg/h per turn), a cable winding up. Shapes in the rate's history
  (rate_history.py argues them and says what they took the place of).

Each is scored like a catalogue effect (the Δχ² of its columns after the
refitted base and the whitening); its threshold is the (1 − α) point of its
best score on the same simulated effect-free data. A probe competes with a
catalogue effect by two nested tests (``gain_given``): the probe must still
add significantly once the effect is fitted, and the effect must add nothing
significant once the probe is fitted; then the probe is the better account of
the data and nothing is named. A probe that adds nothing beyond the effect either
(the two nearly collinear) must explain more than it by more than a probe does when
the effect is true (``arbitration.excess_if_effect_true``): when the data cannot tell
the two apart the catalogue effect is named, its probability shared with the probe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from scipy import stats

from gyrocal.analysis.discrepancy.rate_history import first_order_memory, net_turns
from gyrocal.analysis.discrepancy.scoring import (
    Fit,
    Whitener,
    order_statistic_quantile,
    score_from_delta,
)
from gyrocal.analysis.discrepancy.segments import Bins
from gyrocal.analysis.discrepancy.transitions import angular_acceleration_dps2, heating_sign

#: Number of step positions a step probe tries.
POSITIONS = 150
#: Number of turning times the |t − t0| ramp tries, between 20 % and 80 % of the record (a turn
#: nearer an end is a linear ramp with a stub, which bias_ramp already is: a 10σ ramp lost 0.17
#: of its probability to a turn at 10 %).
ABS_RAMP_POSITIONS = 40
#: Start times and time constants the decaying-step probe tries (start times between 10 % and
#: 90 % of the record, τ log-spaced from three bins to a third of the record, like the
#: catalogue's warm-up): 60 × 6 single columns, one matrix product against the null draws.
DECAY_POSITIONS = 60
DECAY_TAUS = 6
#: Time constants the spin-heating probe tries, for |ω| and for ω² (log-spaced like the
#: decaying step's): 2 × 8 single columns.
SPIN_TAUS = 8
#: Most frequencies the slow-sinusoid probe tries.
MAX_FREQUENCIES = 200
_DPH_PER_PPM_PER_DPS = 3600.0 * 1e-6


class ProbeKind(Enum):
    BIAS_STEP = "bias step"
    SF_STEP = "scale-factor step"
    SLOW_SINE = "slow sinusoid"
    TIME_CUBIC = "cubic in time"
    ABS_TIME_RAMP = "ramp in |t - t0|"
    ONE_SIGN_RATE2 = "rate squared on one rate sign"
    RATE_SIGN_BIAS = "bias by rate sign"
    ABS_TEMP_RATE = "term in |dT/dt|"
    TEMP_RATE_X_TEMP = "term in dT/dt x (T - mean T)"
    TEMP_CUBIC = "bias cubic in temperature"
    SF_TIME_RAMP = "scale factor drifting with time"
    DECAYING_STEP = "decaying bias step"
    SIGNED_RATE2 = "rate squared with the rate's sign"
    ABS_RATE_X_TEMP = "term in |rate| x (T - reference)"
    RATE2_X_TEMP = "term in rate squared x (T - reference)"
    TEMP_RATE_SIGN = "bias by the sign of dT/dt"
    HEAT_COOL_LEVELS = "bias levels while heating and while cooling"
    TABLE_ACCEL = "bias in table angular acceleration"
    SPIN_HEAT = "bias from table spin heating"
    NET_TURNS = "bias in net table turns"


@dataclass(frozen=True)
class ProbeInputs:
    """What the probes' shapes are made of, per sample; with ``bins``, shapes come out binned.

    ``t_s`` counts from the record start. Shapes in time only (steps, sinusoid,
    cubic, |t − t0|) are evaluated at the bin centres; shapes nonlinear in rate or
    temperature are evaluated per sample and then averaged, as the catalogue's are
    (ω² of a bin's mean rate is not the mean of ω² over a slew).
    """

    t_s: np.ndarray
    rate_dps: np.ndarray
    temp_c: np.ndarray
    temp_rate_c_per_min: np.ndarray
    bins: Bins | None = None
    #: binned shapes already averaged over the samples (an overnight log has 10 M of them)
    _cache: dict = field(default_factory=dict, compare=False, repr=False)
    #: ΔT of the rate-temperature probes is about it (the model's); None: the record's mean
    reference_temp_c: float | None = None

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if self.bins is None else float(self.t_s[-1])

    @property
    def time_s(self) -> np.ndarray:
        return self.t_s if self.bins is None else self.bins.centre_s

    def reduce(self, per_sample: np.ndarray) -> np.ndarray:
        return per_sample if self.bins is None else self.bins.mean(per_sample)

    @property
    def step_s(self) -> float:
        """The spacing of the shapes' points: a bin's width, or the sample interval."""
        return self.bins.width_s if self.bins is not None else float(self.t_s[1] - self.t_s[0])


def probe_columns(kind: ProbeKind, where: float, x: ProbeInputs, tau_s: float = 0.0) -> np.ndarray:
    """The probe's regressors (n × dof) at ``where`` (a time, a frequency or a rate sign).

    ``tau_s`` is the decaying step's and the spin heating's time constant (``where`` is the
    spin heating's power of |ω|).
    """
    t = x.time_s
    if kind is ProbeKind.SPIN_HEAT:
        return first_order_memory(_cached(x, (kind, where), lambda: x.reduce(np.abs(x.rate_dps) ** where)),
                                  x.step_s, tau_s)[:, None]
    if kind is ProbeKind.DECAYING_STEP:
        return np.where(t >= where, np.exp(-np.maximum(t - where, 0.0) / tau_s), 0.0)[:, None]
    if kind is ProbeKind.BIAS_STEP:
        return (t >= where).astype(float)[:, None]
    if kind is ProbeKind.SF_STEP:
        return np.where(t >= where, _DPH_PER_PPM_PER_DPS * x.reduce(x.rate_dps), 0.0)[:, None]
    if kind is ProbeKind.SLOW_SINE:
        phase = 2.0 * math.pi * where * t
        return np.column_stack([np.cos(phase), np.sin(phase)])
    if kind is ProbeKind.TIME_CUBIC:
        u = (t - 0.5 * x.duration_s) / (0.5 * x.duration_s)
        return np.column_stack([u, u * u, u ** 3])
    if kind is ProbeKind.ABS_TIME_RAMP:
        return (np.abs(t - where) / 3600.0)[:, None]
    if kind is ProbeKind.SF_TIME_RAMP:      # ppm per hour: ω·1e-6·ppm·t/3600, deg/h
        return (_DPH_PER_PPM_PER_DPS * x.reduce(x.rate_dps) * t / 3600.0)[:, None]
    return _cached(x, (kind, where), lambda: _sample_shape(kind, where, x))


def _cached(x: ProbeInputs, key: tuple, make) -> np.ndarray:
    """A binned shape averaged over the samples once per record (per-sample shapes are not kept)."""
    if x.bins is None:
        return make()
    if key not in x._cache:
        x._cache[key] = make()
    return x._cache[key]


def _sample_shape(kind: ProbeKind, where: float, x: ProbeInputs) -> np.ndarray:
    """Shapes nonlinear in rate or temperature: per sample, then binned (``x.reduce``)."""
    w = x.rate_dps
    if kind is ProbeKind.ONE_SIGN_RATE2:
        return x.reduce(np.where(np.sign(w) == where, w * w, 0.0))[:, None]
    if kind is ProbeKind.RATE_SIGN_BIAS:
        return x.reduce(np.sign(w))[:, None]
    if kind is ProbeKind.ABS_TEMP_RATE:
        return x.reduce(np.abs(x.temp_rate_c_per_min))[:, None]
    if kind is ProbeKind.TEMP_RATE_SIGN:
        return x.reduce(heating_sign(x.t_s, x.temp_c))[:, None]
    if kind is ProbeKind.HEAT_COOL_LEVELS:
        sign = heating_sign(x.t_s, x.temp_c)
        return np.column_stack([x.reduce((sign > 0).astype(float)), x.reduce((sign < 0).astype(float))])
    if kind is ProbeKind.TABLE_ACCEL:
        return x.reduce(angular_acceleration_dps2(x.t_s, w))[:, None]
    if kind is ProbeKind.NET_TURNS:
        return x.reduce(net_turns(w, float(x.t_s[1] - x.t_s[0])))[:, None]
    if kind is ProbeKind.TEMP_CUBIC:
        dt = x.temp_c - float(np.mean(x.temp_c))
        return np.column_stack([x.reduce(dt * dt), x.reduce(dt ** 3)])
    if kind in _RATE_SHAPES:
        return x.reduce(_RATE_SHAPES[kind](w, x.temp_c - (
            float(np.mean(x.temp_c)) if x.reference_temp_c is None else x.reference_temp_c)))[:, None]
    return x.reduce(x.temp_rate_c_per_min * (x.temp_c - float(np.mean(x.temp_c))))[:, None]


@dataclass(frozen=True)
class Probe:
    """The best instance of one generic shape, and whether it stands out of the noise."""

    kind: ProbeKind
    where: float          # time (s from the record start), frequency (Hz) or rate sign; 0 if none
    coeffs: tuple[float, ...]   # one per column of ``probe_columns`` (units in ``describe``)
    delta_chi2: float
    dof: int
    threshold: float
    n_candidates: int
    #: the whitened, unprojected columns of the best instance (for the nested tests)
    white_columns: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), compare=False,
                                      repr=False)
    #: the decaying step's time constant (s); 0 for every other kind
    tau_s: float = 0.0
    #: its best score on each simulated effect-free dataset (the column of the family maximum
    #: that ``adequacy.family_threshold`` calibrates against)
    null: np.ndarray = field(default_factory=lambda: np.zeros(0), compare=False, repr=False)

    @property
    def score(self) -> float:
        return score_from_delta(self.delta_chi2, self.dof)

    @property
    def significant(self) -> bool:
        return self.score > self.threshold

    @property
    def penalised_delta(self) -> float:
        """Δχ² less what searching its grid buys on noise alone (2 ln M) and ln n per column
        beyond one (BIC): how probes of different flexibility are ranked against each other."""
        return self.penalised_against(1, self.white_columns.shape[0])

    def penalised_against(self, dof: int, n_bins: int) -> float:
        """Δχ² to hold against a catalogue effect of ``dof`` columns: less the search penalty
        (2 ln M) and ln n per extra column (BIC), so a probe that merely nests the effect
        (the cubic in time nests bias_ramp) does not win on the χ²₂ its extra columns buy."""
        return (self.delta_chi2 - 2.0 * math.log(max(self.n_candidates, 1))
                - max(self.dof - dof, 0) * math.log(max(n_bins, 2)))

    @property
    def time_s(self) -> float:
        return self.where

    @property
    def size(self) -> float:
        """The amplitude of the shape (deg/h, ppm, deg/h per hour ...; see ``describe``)."""
        if self.kind is ProbeKind.SLOW_SINE:
            return math.hypot(*self.coeffs)
        if self.kind is ProbeKind.TEMP_CUBIC:
            return self.coeffs[1]
        if self.kind is ProbeKind.HEAT_COOL_LEVELS:
            return max(self.coeffs, key=abs)
        if self.kind is ProbeKind.TIME_CUBIC:
            u = np.linspace(-1.0, 1.0, 201)
            curve = self.coeffs[0] * u + self.coeffs[1] * u * u + self.coeffs[2] * u ** 3
            return float(np.ptp(curve))
        return self.coeffs[0]

    @property
    def size_dph(self) -> float:
        return self.size

    def signal_dph(self, x: ProbeInputs) -> np.ndarray:
        """The fitted probe on ``x`` (per bin or per sample), deg/h."""
        return probe_columns(self.kind, self.where, x, self.tau_s) @ np.asarray(self.coeffs)

    def describe(self) -> str:
        k, s = self.kind, self.size
        if k is ProbeKind.SLOW_SINE:
            return f"a slow sinusoid of {s:.3g} deg/h, period {1.0 / self.where:.0f} s"
        if k is ProbeKind.TIME_CUBIC:
            a, b, c = self.coeffs
            return (f"a bias curving in time (cubic over the record: {a:+.3g}·u {b:+.3g}·u² "
                    f"{c:+.3g}·u³ deg/h, u = −1…+1; {s:.3g} deg/h peak to peak)")
        if k is ProbeKind.TEMP_CUBIC:
            return (f"a bias cubic in temperature, {self.coeffs[0]:+.3g}·ΔT² {s:+.3g}·ΔT³ deg/h "
                    "(ΔT in degC about the record's mean)")
        if k is ProbeKind.ONE_SIGN_RATE2:
            sign = "positive" if self.where > 0 else "negative"
            return f"a rate² term on {sign} rates only of {s:+.3g} deg/h per (deg/s)²"
        if k is ProbeKind.DECAYING_STEP:
            return (f"a bias step of {s:+.3g} deg/h near t = {self.where:.0f} s decaying with "
                    f"τ {self.tau_s:.0f} s")
        if k is ProbeKind.SPIN_HEAT:
            rate, per = ("|ω|", "deg/s") if self.where == 1.0 else ("ω²", "(deg/s)²")
            return (f"a bias from table spin heating: {rate} through a first-order memory of τ "
                    f"{self.tau_s:.0f} s, {s:+.3g} deg/h per {per} once settled")
        if k is ProbeKind.RATE_SIGN_BIAS:
            return f"a bias by rate sign of ±{abs(s):.3g} deg/h ({'+' if s > 0 else '−'} for positive rates)"
        if k is ProbeKind.TEMP_RATE_SIGN:
            return (f"a bias by the sign of dT/dt of ±{abs(s):.3g} deg/h ({'+' if s > 0 else '−'} while the "
                    "chamber heats, zero in soaks; not proportional to dT/dt)")
        if k is ProbeKind.HEAT_COOL_LEVELS:
            return (f"a bias of {self.coeffs[0]:+.3g} deg/h while the chamber heats and {self.coeffs[1]:+.3g} "
                    "deg/h while it cools, zero in soaks (two levels, not proportional to dT/dt)")
        if k is ProbeKind.TABLE_ACCEL:
            lag = (f"; a rate-output lag of {-s / 3600.0:.3g} s would give it" if s < 0 else "")
            return (f"a bias in the table's angular acceleration of {s:+.3g} deg/h per deg/s² "
                    f"(in slews only{lag})")
        return _DESCRIPTIONS[k].format(s=s, where=self.where)


#: how ``Probe.describe`` words the kinds that need only their size ``s`` and ``where``
_DESCRIPTIONS: dict[ProbeKind, str] = {
    ProbeKind.BIAS_STEP: "a bias step of {s:+.3g} deg/h near t = {where:.0f} s",
    ProbeKind.SF_STEP: "a scale-factor step of {s:+.3g} ppm near t = {where:.0f} s",
    ProbeKind.ABS_TIME_RAMP:
        "a bias ramp in |t − t0| of {s:+.3g} deg/h per hour turning at t0 = {where:.0f} s",
    ProbeKind.SF_TIME_RAMP: "a scale factor drifting by {s:+.3g} ppm per hour",
    ProbeKind.NET_TURNS:
        "a bias ∝ the net table turns since the start (a cable winding up) of {s:+.3g} deg/h per turn",
    ProbeKind.ABS_TEMP_RATE:
        "a bias in |dT/dt| of {s:+.3g} deg/h per degC/min (same sign heating and cooling)",
    ProbeKind.TEMP_RATE_X_TEMP: "a bias in dT/dt·(T − mean T) of {s:+.3g} deg/h per degC·degC/min",
    ProbeKind.SIGNED_RATE2: "a rate² term with the rate's sign (ω·|ω|) of {s:+.3g} deg/h per (deg/s)²",
    ProbeKind.ABS_RATE_X_TEMP:
        "a bias in |ω|·ΔT of {s:+.3g} deg/h per deg/s·degC (ΔT from the model's reference temperature)",
    ProbeKind.RATE2_X_TEMP:
        "a rate² growing with temperature, ω²·ΔT, of {s:+.3g} deg/h per (deg/s)²·degC "
        "(ΔT from the model's reference temperature)",
}

#: the per-sample shapes of the probes in rate (and temperature), of (ω deg/s, ΔT degC)
_RATE_SHAPES = {
    ProbeKind.SIGNED_RATE2: lambda w, dt: w * np.abs(w),
    ProbeKind.ABS_RATE_X_TEMP: lambda w, dt: np.abs(w) * dt,
    ProbeKind.RATE2_X_TEMP: lambda w, dt: w * w * dt,
}


def step_columns(n_bins: int, positions: np.ndarray) -> np.ndarray:
    """Unit bias steps starting at each bin position."""
    return (np.arange(n_bins)[:, None] >= positions[None, :]).astype(float)


def _null_scores(gains: np.ndarray, dof: int) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return -stats.chi2.logsf(gains, dof) / math.log(10.0)


def _projected(columns: np.ndarray, fit: Fit, whitener: Whitener) -> tuple[np.ndarray, np.ndarray]:
    white = whitener.white(columns)
    return white, white - fit.basis @ (fit.basis.T @ white)


def _fitted(kind: ProbeKind, where: float, x: ProbeInputs, fit: Fit, whitener: Whitener,
            threshold: float, n_candidates: int, null: np.ndarray, tau_s: float = 0.0) -> Probe | None:
    """The probe at ``where`` fitted to the residual (its coefficients and Δχ²)."""
    white, perp = _projected(probe_columns(kind, where, x, tau_s), fit, whitener)
    coef, *_ = np.linalg.lstsq(perp, fit.white_resid, rcond=None)
    explained = perp @ coef
    if not np.all(np.isfinite(coef)):
        return None
    return Probe(kind, float(where), tuple(float(c) for c in coef), float(explained @ explained),
                 white.shape[1], threshold, n_candidates, white, tau_s, null)


def _single_column_family(kind: ProbeKind, where: np.ndarray, x: ProbeInputs, fit: Fit,
                          whitener: Whitener, z: np.ndarray, alpha: float) -> Probe | None:
    """One column per candidate (a step or turning time, a sign): vectorised over candidates."""
    columns = np.column_stack([probe_columns(kind, float(w), x)[:, 0] for w in where])
    best = _best_column(columns, fit, whitener, z, alpha)
    if best is None:
        return None
    k, threshold, null, count = best
    return _fitted(kind, float(where[k]), x, fit, whitener, threshold, count, null)


def _best_column(columns: np.ndarray, fit: Fit, whitener: Whitener, z: np.ndarray, alpha: float
                 ) -> tuple[int, float, np.ndarray, int] | None:
    """The column that best explains the residual, the (1 − α) point of the best on the null
    draws, those null scores, and how many columns were usable (not spanned by the base)."""
    _, perp = _projected(columns, fit, whitener)
    norms = np.linalg.norm(perp, axis=0)
    usable = norms > 1e-9 * max(float(norms.max()), 1e-300)
    if not usable.any():
        return None
    q = perp[:, usable] / norms[usable]
    k = int(np.argmax((q.T @ fit.white_resid) ** 2))
    null = _null_scores(np.max((q.T @ z) ** 2, axis=0), 1)
    threshold = order_statistic_quantile(null, 1.0 - alpha)
    return int(np.flatnonzero(usable)[k]), threshold, null, int(usable.sum())


def decaying_step_probe(fit: Fit, whitener: Whitener, x: ProbeInputs, z: np.ndarray,
                        alpha: float) -> Probe | None:
    """The best decaying bias step over start times and time constants (one column each)."""
    duration_s = x.duration_s
    width_s = duration_s / max(len(x.time_s), 1)
    starts = duration_s * np.linspace(0.1, 0.9, DECAY_POSITIONS)
    top = max(duration_s / 3.0, 6.0 * width_s)
    taus = np.geomspace(min(3.0 * width_s, top / 2.0), top, DECAY_TAUS)
    pairs = [(float(t0), float(tau)) for t0 in starts for tau in taus]
    return _best_of_grid(ProbeKind.DECAYING_STEP, pairs, x, fit, whitener, z, alpha)


def spin_heat_probe(fit: Fit, whitener: Whitener, x: ProbeInputs, z: np.ndarray,
                    alpha: float) -> Probe | None:
    """The best of |ω| and ω² through a first-order memory, over time constants (one column each)."""
    duration_s = x.duration_s
    top = max(duration_s / 3.0, 6.0 * x.step_s)
    taus = np.geomspace(min(3.0 * x.step_s, top / 2.0), top, SPIN_TAUS)
    pairs = [(power, float(tau)) for power in (1.0, 2.0) for tau in taus]
    return _best_of_grid(ProbeKind.SPIN_HEAT, pairs, x, fit, whitener, z, alpha)


def _best_of_grid(kind: ProbeKind, grid: list[tuple[float, float]], x: ProbeInputs, fit: Fit,
                  whitener: Whitener, z: np.ndarray, alpha: float) -> Probe | None:
    """The best single column over a grid of (where, τ) shapes of a two-parameter probe, its
    threshold from the same null draws as every probe's (one matrix product for the grid)."""
    columns = np.column_stack([probe_columns(kind, where, x, tau)[:, 0] for where, tau in grid])
    best = _best_column(columns, fit, whitener, z, alpha)
    if best is None:
        return None
    k, threshold, null, count = best
    where, tau = grid[k]
    return _fitted(kind, where, x, fit, whitener, threshold, count, null, tau)


def _one_shape(kind: ProbeKind, x: ProbeInputs, fit: Fit, whitener: Whitener, z: np.ndarray,
               alpha: float) -> Probe | None:
    """A probe with one fixed shape of one or more columns (no search)."""
    _, perp = _projected(probe_columns(kind, 0.0, x), fit, whitener)
    q, r = np.linalg.qr(perp)
    good = np.abs(np.diag(r)) > 1e-7 * max(float(np.abs(np.diag(r)).max()), 1e-300)
    if not good.any():
        return None
    q = q[:, good]
    null = _null_scores(np.sum((q.T @ z) ** 2, axis=0), q.shape[1])
    threshold = order_statistic_quantile(null, 1.0 - alpha)
    return _fitted(kind, 0.0, x, fit, whitener, threshold, 1, null)


def slow_sine_probe(fit: Fit, whitener: Whitener, bins: Bins, x: ProbeInputs, z: np.ndarray,
                    alpha: float) -> Probe | None:
    duration_s = bins.n_bins * bins.width_s
    f_lo, f_hi = 2.0 / duration_s, 1.0 / (8.0 * bins.width_s)
    count = int(min(MAX_FREQUENCIES, max(2, (f_hi - f_lo) * duration_s * 2)))
    freqs = np.geomspace(f_lo, f_hi, count)
    phase = 2.0 * math.pi * bins.centre_s[:, None] * freqs[None, :]
    a, b = (_projected(part, fit, whitener)[1] for part in (np.cos(phase), np.sin(phase)))
    g11, g12, g22 = np.sum(a * a, 0), np.sum(a * b, 0), np.sum(b * b, 0)
    det = g11 * g22 - g12 * g12
    usable = det > 1e-9 * max(float(np.max(det)), 1e-300)
    if not usable.any():
        return None

    def gains(r: np.ndarray) -> np.ndarray:
        u, v = a.T @ r, b.T @ r
        out = (g22[:, None] * u * u - 2 * g12[:, None] * u * v + g11[:, None] * v * v) / np.where(
            usable, det, 1.0)[:, None]
        return np.where(usable[:, None], out, 0.0)

    k = int(np.argmax(gains(fit.white_resid[:, None])[:, 0]))
    null = _null_scores(np.max(gains(z), axis=0), 2)
    threshold = order_statistic_quantile(null, 1.0 - alpha)
    return _fitted(ProbeKind.SLOW_SINE, float(freqs[k]), x, fit, whitener, threshold, int(usable.sum()), null)


def all_probes(fit: Fit, whitener: Whitener, bins: Bins, x: ProbeInputs, z: np.ndarray,
               alpha: float) -> list[Probe]:
    """Every probe the record can show (rate terms need a turning table, dT/dt terms a ramp)."""
    n = bins.n_bins
    steps = np.unique(np.linspace(0.02 * n, 0.98 * n, POSITIONS).astype(int))
    step_times = bins.centre_s[steps] - bins.width_s / 2
    turning = x.duration_s * np.linspace(0.2, 0.8, ABS_RAMP_POSITIONS)
    probes = [_single_column_family(ProbeKind.BIAS_STEP, step_times, x, fit, whitener, z, alpha),
              slow_sine_probe(fit, whitener, bins, x, z, alpha),
              _one_shape(ProbeKind.TIME_CUBIC, x, fit, whitener, z, alpha),
              _single_column_family(ProbeKind.ABS_TIME_RAMP, turning, x, fit, whitener, z, alpha),
              decaying_step_probe(fit, whitener, x, z, alpha)]
    if np.any(np.abs(x.rate_dps) > 0):
        probes += [_single_column_family(ProbeKind.SF_STEP, step_times, x, fit, whitener, z, alpha),
                   _one_shape(ProbeKind.SF_TIME_RAMP, x, fit, whitener, z, alpha),
                   spin_heat_probe(fit, whitener, x, z, alpha),
                   _one_shape(ProbeKind.NET_TURNS, x, fit, whitener, z, alpha)]
    if np.any(x.rate_dps > 0) and np.any(x.rate_dps < 0):
        probes += [_single_column_family(ProbeKind.ONE_SIGN_RATE2, np.array([1.0, -1.0]), x, fit,
                                         whitener, z, alpha),
                   _one_shape(ProbeKind.RATE_SIGN_BIAS, x, fit, whitener, z, alpha),
                   _one_shape(ProbeKind.SIGNED_RATE2, x, fit, whitener, z, alpha)]
    if np.any(np.abs(x.rate_dps) > 0) and np.ptp(x.temp_c) > 1.0:
        probes += [_one_shape(kind, x, fit, whitener, z, alpha)
                   for kind in (ProbeKind.ABS_RATE_X_TEMP, ProbeKind.RATE2_X_TEMP)]
    if np.ptp(x.temp_c) > 1.0:
        probes.append(_one_shape(ProbeKind.TEMP_CUBIC, x, fit, whitener, z, alpha))
    if np.ptp(x.temp_rate_c_per_min) > 0.1:
        probes += [_one_shape(kind, x, fit, whitener, z, alpha) for kind in
                   (ProbeKind.ABS_TEMP_RATE, ProbeKind.TEMP_RATE_X_TEMP, ProbeKind.TEMP_RATE_SIGN,
                    ProbeKind.HEAT_COOL_LEVELS)]
    if np.ptp(x.rate_dps) > 0:
        probes.append(_one_shape(ProbeKind.TABLE_ACCEL, x, fit, whitener, z, alpha))
    return [p for p in probes if p is not None]


def strongest(probes: list[Probe]) -> Probe | None:
    """The significant probe with the largest penalised gain, if any is significant."""
    ranked = significant_by_strength(probes)
    return ranked[0] if ranked else None


def significant_by_strength(probes: list[Probe]) -> list[Probe]:
    """The significant probes, the largest penalised gain first."""
    return sorted((p for p in probes if p.significant), key=lambda p: -p.penalised_delta)


def gain_given(probe: Probe, basis: np.ndarray, white_resid: np.ndarray) -> float:
    """Δχ² of the probe's shape added to a fit whose whitened basis and residual are given.

    The nested test both ways between a probe and a catalogue effect: with the
    effect's fit, the probe's gain says whether the probe explains something the
    effect leaves; the effect's gain beyond the probe is Δ_E + gain(P|E) − Δ_P.
    """
    perp = probe.white_columns - basis @ (basis.T @ probe.white_columns)
    q, r = np.linalg.qr(perp)
    good = np.abs(np.diag(r)) > 1e-7 * max(float(np.abs(np.diag(r)).max()), 1e-300)
    proj = q[:, good].T @ white_resid
    return float(proj @ proj)
