"""Each named effect's gap in the metric where that effect lives, before and after, beside its floor.

A whole-record metric (G1 over every segment, the spectrum peak) can sit at
its floor while a named effect is real: a quantization pulse changes nothing
in segment means, a thermal lag lives in three ramp segments out of forty. So
every named effect gets its own metrics, in its own domain.

**The floor** of every metric (gap.FLOOR_DEFINITION) is the level the metric
stays at or below under noise alone, effect-free residuals through the same
refit, with probability ``FLOOR_PROBABILITY`` (0.9); its mean under noise
alone is ``noise_mean``. It was that mean before: a metric whose after-gap is
one |N(0, 1)|-sized number then passed 1.5× its floor by chance in 23 % of
runs (dead_zone: 3 of 12 held-out runs on R1–R3), so "after ≤ 1.5× floor"
could not tell a closed gap from noise. Against the 90 % point, noise alone
passes 1.5× the floor in 1.4 % of runs at one degree of freedom and in less
with more, while a claim named near its threshold still starts at ≥ 2× a
one-dof floor (2 × 1.645 sd = 3.29 sd; the lowest pattern amplitude of 108
named runs on P1/Q1–Q3 at 5σ and 10σ was 3.6 sd; at the 95 % point, 3.92 sd,
it would not). Per effect:

* **quantization**: the Allan deviation of the full-rate residual at the
  shortest τ (1, 2, 4, 8 samples) over the record in ``SHORT_TAU_CHUNKS``
  parts, held against the gyro model's noise (before: the model as given;
  after: the pulse counter run on the model's predicted rate plus its white
  noise, simulated — a 0/1-pulse readout is not white angle noise of q/√12);
  RMS over parts and τ of ln(measured / model). Floor: the 90 % point of the
  same statistic of each simulated draw against the others (with 12 draws,
  their largest: P(new ≤ it) = 12/13).
* **periodic_interference**: the spectrum peak (periodic.py); floor the 90 %
  point of the max of M exponentials (gap.max_exponential_quantile).
* **markov_bias**: the Allan mismatch over the τ it owns (``markov_metrics``),
  each τ in units of its noise-alone spread; floor the 90 % point over the
  effect-free draws through the final refit.
* every other (deterministic) effect: the segments where its fitted signature
  stands out (segment means of its contribution over their standard errors,
  the largest ones that hold ``SHARE`` of its Σz²: ramp segments for a
  temperature effect, dwells for a rate effect), and two metrics there:

  - the **pattern amplitude** (deg/h): the GLS amplitude of the effect's
    base-projected pattern in the residual (how much of the named effect the
    residual still holds, 1 = all of it), times the RMS of the pattern's segment
    means over its segments. Before ≈ the effect's size, after ≈ 0 once it is
    fitted; noise alone makes it |N(0, σ²)|, σ exact from the whitening: floor
    1.645σ (mean 0.80σ);
  - **G1 of its segments**: G1 (gap.py) over those segments only; noise alone
    through the final refit makes it a quadratic form in white noise, floor
    its 90 % point from the form's eigenvalues (gap.g1_null_floor).

  **dead_zone** has no fitted amplitude (only its threshold), so its pattern
  amplitude after the fit is one noise draw, not ≈ 0: it is headed instead by
  G1 over every dwell inside or near the zone and the segments holding its
  signature (``dwell_metrics``), as many degrees of freedom as segments, and
  anything else left in those dwells shows there too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gyrocal.analysis.discrepancy.gap import (
    FLOOR_PROBABILITY,
    AllanRatios,
    Metric,
    SegmentGeometry,
    g1_null_floor,
)
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.models.pulse_counting import PulseCounter

#: The averaging times a Markov bias owns, in its correlation time, and the fewest taken.
MARKOV_SPAN = (0.25, 8.0)
MARKOV_MIN_TAUS = 3
#: Share of an effect's Σz² over segments that its segments must hold.
SHARE = 0.9
#: Shortest averaging factors (samples) of the quantization metric.
SHORT_M = np.array([1, 2, 4, 8])
#: Most samples the short-τ Allan deviation is computed on (the start of the record: 2.8 h at 100 Hz).
SHORT_TAU_SAMPLES = 1_000_000
#: Parts of the record the short-τ Allan deviation is compared in, each on its own.
SHORT_TAU_CHUNKS = 4
#: Draws of white noise for the short-τ floor.
SHORT_TAU_DRAWS = 12
#: E|x| and sd|x| of x ~ N(0, 1): the mean and spread of a pattern amplitude's magnitude under noise.
_ABS_MEAN, _ABS_SD = math.sqrt(2.0 / math.pi), math.sqrt(1.0 - 2.0 / math.pi)
#: The FLOOR_PROBABILITY point of |x|, x ~ N(0, 1): a pattern amplitude's floor, in its sd.
_ABS_FLOOR = float(stats.norm.ppf(0.5 + FLOOR_PROBABILITY / 2.0))


@dataclass(frozen=True)
class Residuals:
    """A residual per bin (deg/h) and whitened (L⁻¹·residual)."""

    bins_dph: np.ndarray
    white: np.ndarray


@dataclass(frozen=True)
class Pattern:
    """A named effect's contribution with what the base refit absorbs projected out, per bin (deg/h)
    and whitened."""

    bins_dph: np.ndarray
    white: np.ndarray


@dataclass(frozen=True)
class EffectGap:
    """One named effect's metrics (name → Metric) and the one that heads its story."""

    effect: str
    metrics: dict[str, Metric]
    headline: str


def effect_segments(contribution_bins: np.ndarray, geometry: SegmentGeometry) -> np.ndarray:
    """Indices of the segments holding ``SHARE`` of the contribution's Σ(mean/stderr)²."""
    z2 = (geometry.means(contribution_bins) / geometry.stderr_dph) ** 2
    order = np.argsort(-z2)
    total = float(z2.sum())
    if not total > 0:
        return order[:1]
    count = int(np.searchsorted(np.cumsum(z2[order]) / total, SHARE) + 1)
    return np.sort(order[:count])


def _segment_kind(names: list[str]) -> str:
    ramps = sum("ramp" in n for n in names)
    moving = sum("moving" in n for n in names)
    dwells = sum("table" in n and "+0 deg/s" not in n and "moving" not in n for n in names)
    parts = [f"{count} {label}" for count, label in ((ramps, "temperature-ramp"), (dwells, "rate-dwell"),
                                                     (moving, "table-moving")) if count]
    return f"{len(names)} segments ({', '.join(parts) or 'soaks, table still'})"


@dataclass(frozen=True)
class NullRefit:
    """How noise alone reaches a residual: r = L·(I − Q·Qᵀ)·w, w white (gap.g1_null_floor)."""

    chol: np.ndarray       # Cholesky factor L of the bin-mean noise covariance
    basis: np.ndarray      # Q: orthonormal basis of the final refit's whitened columns


def segment_g1_metric(segments: np.ndarray, before: np.ndarray, after: np.ndarray,
                      null: NullRefit, geometry: SegmentGeometry, what: str) -> Metric:
    """G1 over ``segments`` before and after, its floor exact from the refit (gap.g1_null_floor)."""
    averaging, stderr = geometry.averaging[:, segments], geometry.stderr_dph[segments]

    def g1_of(resid: np.ndarray) -> float:
        return float(np.mean(((averaging.T @ resid) / stderr) ** 2))

    floor, mean, spread = g1_null_floor(geometry, segments, null.chol, null.basis)
    return Metric(g1_of(before), g1_of(after), floor, spread, "1 (mean of z²)", what, mean)


def pattern_metrics(effect: str, pattern: Pattern, before: Residuals, after: Residuals,
                    null: NullRefit, geometry: SegmentGeometry, segment_names: list[str]) -> EffectGap:
    """The pattern amplitude and G1 over the effect's own segments (see the module docstring)."""
    segments = effect_segments(pattern.bins_dph, geometry)
    norm2 = float(pattern.white @ pattern.white)
    if not norm2 > 0:
        return EffectGap(effect, {}, "")
    c = geometry.averaging[:, segments].T @ pattern.bins_dph
    rms = float(np.sqrt(np.mean(c * c)))
    sd = rms / math.sqrt(norm2)

    def amplitude_of(resid: Residuals) -> float:
        return abs(float(pattern.white @ resid.white)) / norm2 * rms

    where = _segment_kind([segment_names[k] for k in segments])
    amplitude = Metric(amplitude_of(before), amplitude_of(after), _ABS_FLOOR * sd, _ABS_SD * sd, "deg/h",
                       f"{effect}: GLS amplitude of its base-projected pattern in the residual, as the "
                       f"RMS of its segment means over its {where}", _ABS_MEAN * sd)
    g1_metric = segment_g1_metric(segments, before.bins_dph, after.bins_dph, null,
                                  geometry, f"{effect}: G1 (segment mean over its standard error, squared, "
                                            f"averaged) over its {where}")
    head = f"{effect}_pattern_dph"
    return EffectGap(effect, {head: amplitude, f"{effect}_segment_g1": g1_metric}, head)


def dwell_metrics(gap: EffectGap, near_rate_dps: float, segment_rate_dps: np.ndarray, before: Residuals,
                  after: Residuals, null: NullRefit, geometry: SegmentGeometry, pattern: Pattern
                  ) -> EffectGap:
    """A dead zone's gap over every dwell inside or near it, beside its pattern metrics (the headline).

    Its pattern amplitude is one number with no fitted amplitude behind it (only the
    threshold is fitted), so its after-gap is one |N(0, 1)|-sized draw: against a floor
    at its mean it passed 1.5× by chance in 3 of 12 held-out runs (R1–R3) and 3 of 12 on
    P1 (benchmarks/validate_own_gap_floor.py). G1 over the segments
    holding its signature and every table dwell with 0 < |rate| ≤ ``near_rate_dps`` (2× the
    threshold: a threshold fitted wrong shows there) has as many degrees of freedom as
    dwells, and whatever else is left in those dwells shows in it too.
    """
    near = np.flatnonzero((np.abs(segment_rate_dps) > 0) & (np.abs(segment_rate_dps) <= near_rate_dps))
    segments = np.union1d(effect_segments(pattern.bins_dph, geometry), near)
    key = f"{gap.effect}_dwell_g1"
    metric = segment_g1_metric(segments, before.bins_dph, after.bins_dph, null, geometry,
                               f"{gap.effect}: G1 over its {len(segments)} segments (the dwells with "
                               f"|rate| ≤ {near_rate_dps:.3g} deg/s and the segments holding its signature): "
                               "(segment mean / its standard error)², averaged")
    return EffectGap(gap.effect, {key: metric, **gap.metrics}, key)


def markov_metrics(effect: str, tau_c_s: float, allan: AllanRatios) -> EffectGap:
    """A Markov bias's gap: the Allan mismatch over the τ it owns, each τ in its own noise spread.

    The whole-record Allan mismatch averages τ where the process adds nothing, and weighs
    the noisy long-τ estimates like the precise short ones. Over ``MARKOV_SPAN`` × its
    correlation time (at least the ``MARKOV_MIN_TAUS`` averaging times nearest its ADEV
    hump at 1.9 τ) each ln(residual ADEV / model ADEV) is taken in units of its spread
    over the effect-free draws through the final refit (less their mean), and the metric
    is the RMS of those. Before: against the noise model without the process; after:
    with it (the whole-record mismatch's own ratios, ``gap.AllanRatios``). Floor: the
    ``FLOOR_PROBABILITY`` point of the same statistic over the draws.
    """
    tau_s = allan.m * allan.width_s
    owned = np.flatnonzero((tau_s >= MARKOV_SPAN[0] * tau_c_s) & (tau_s <= MARKOV_SPAN[1] * tau_c_s))
    if len(owned) < MARKOV_MIN_TAUS:
        owned = np.sort(np.argsort(np.abs(np.log(tau_s / (1.9 * tau_c_s))))[:MARKOV_MIN_TAUS])
    null = allan.null[:, owned]
    centre, spread = null.mean(axis=0), np.maximum(null.std(axis=0), 1e-12)

    def mismatch(log_ratio: np.ndarray) -> np.ndarray:
        return np.sqrt(np.mean(((log_ratio - centre) / spread) ** 2, axis=-1))

    key = f"{effect}_allan_mismatch"
    metric = Metric.of_null(float(mismatch(allan.before[owned])), float(mismatch(allan.after[owned])),
                            mismatch(null), "1 (RMS of z)",
                            f"{effect}: Allan deviation of the residual's bin means against the noise model "
                            f"without (before) and with (after) it over τ = {tau_s[owned[0]]:.3g}–"
                            f"{tau_s[owned[-1]]:.3g} s (around its τ {tau_c_s:.3g} s): RMS of "
                            "ln(measured / model) in units of its noise-alone spread at each τ")
    return EffectGap(effect, {key: metric}, key)


def short_tau_avar_chunks(resid_dph: np.ndarray, fs_hz: float) -> np.ndarray:
    """Overlapping Allan variance at τ = ``SHORT_M`` samples in each of ``SHORT_TAU_CHUNKS`` parts (parts × τ).

    The overlapping Allan variance is the mean of the phase's squared second differences
    over 2τ²; the same mean taken part by part splits it without loss (the record's own
    value is the mean over the parts), so the quantization metric has one ln ratio per
    part and τ instead of one per τ, at the cost of two cumulative sums.
    """
    phase = np.concatenate(([0.0], np.cumsum(resid_dph))) / fs_hz
    out = np.empty((SHORT_TAU_CHUNKS, len(SHORT_M)))
    for j, m in enumerate(SHORT_M):
        d = phase[2 * m:] - 2.0 * phase[m:-m] + phase[:-2 * m]
        tau_s = m / fs_hz
        out[:, j] = [float(np.mean(part**2)) / (2.0 * tau_s**2) for part in np.array_split(d, SHORT_TAU_CHUNKS)]
    return out


def _ln_rms(avar: np.ndarray, reference: np.ndarray) -> float:
    """RMS over parts and τ of ln(ADEV / reference ADEV), from variances."""
    return float(np.sqrt(np.mean((0.5 * np.log(avar / reference)) ** 2)))


def counted_residual_dph(predicted_dph: np.ndarray, fs_hz: float, white_sigma_dph: float,
                         pulse_arcsec: float, rng: np.random.Generator) -> np.ndarray:
    """One draw of the residual a pulse-counting gyro leaves against the model's prediction.

    The model's white rate noise on the predicted rate, counted in whole pulses
    (models/pulse_counting.py, random initial phase), minus the prediction. Not white
    angle noise of q/√12: at 20–50 Hz a 1″ pulse advances by a fraction of a pulse per
    sample while the table is still, so each readout is 0 or 1 pulse with variance
    f(1 − f) and the count error is correlated from sample to sample; only the counter
    itself run on the record's own rate history gives the short-τ Allan curve it leaves.
    """
    noisy_dps = (predicted_dph + rng.standard_normal(len(predicted_dph)) * white_sigma_dph) / 3600.0
    counter = PulseCounter(pulse_arcsec, float(rng.uniform()))
    return counter.quantize(noisy_dps, 1.0 / fs_hz) * 3600.0 - predicted_dph


def quantization_metrics(resid_full_dph: np.ndarray, predicted_dph: np.ndarray, fs_hz: float,
                         given: NoiseModel, pulse_arcsec: float, rng: np.random.Generator) -> EffectGap:
    """Short-τ Allan deviation of the full-rate residual against the model without and with the pulse.

    Over the record (up to ``SHORT_TAU_SAMPLES``) in ``SHORT_TAU_CHUNKS`` parts
    (``short_tau_avar_chunks``). Before: against the given noise model's Allan curve (no
    pulse). After: against the mean, part by part, of ``SHORT_TAU_DRAWS`` simulated
    residuals of the pulse counter run on the model's predicted rate
    (``counted_residual_dph``). Floor: the ``FLOOR_PROBABILITY`` point of the same
    statistic of each simulated draw against the mean of the others (leave one out;
    with 12 draws their largest, which a new noise-alone value stays under with
    probability 12/13). With one part and its mean as the floor, the after-gap of the
    pulse's own simulation passed 1.5× the floor in 4 of 12 P1 runs.
    """
    n = min(len(resid_full_dph), SHORT_TAU_SAMPLES)
    resid, predicted = resid_full_dph[:n], predicted_dph[:n]
    white_dph = given.white_sigma_dph(fs_hz)
    draws = np.array([short_tau_avar_chunks(counted_residual_dph(predicted, fs_hz, white_dph, pulse_arcsec, rng),
                                            fs_hz) for _ in range(SHORT_TAU_DRAWS)])
    measured = short_tau_avar_chunks(resid, fs_hz)
    total = draws.sum(axis=0)
    null = np.array([_ln_rms(draw, (total - draw) / (len(draws) - 1)) for draw in draws])
    model_avar = given.allan_deviation_dph(SHORT_M / fs_hz) ** 2
    metric = Metric.of_null(_ln_rms(measured, np.broadcast_to(model_avar, measured.shape)),
                            _ln_rms(measured, total / len(draws)), null, "1 (RMS of ln ratio)",
                            f"quantization: Allan deviation of the full-rate residual at τ = 1, 2, 4, 8 samples "
                            f"in each of {SHORT_TAU_CHUNKS} parts of the record, against the gyro model's noise "
                            "(before) and against the pulse counter run on the model's predicted rate (after), "
                            "RMS over parts and τ of ln(measured / model)")
    return EffectGap("quantization", {"quantization_short_tau_allan": metric}, "quantization_short_tau_allan")
