"""Each named effect's gap in the metric where that effect lives, before and after, beside its floor.

A whole-record metric (G1 over every segment, the spectrum peak) can sit at
its floor while a named effect is real: a quantization pulse changes nothing
in segment means, a thermal lag lives in three ramp segments out of forty. So
every named effect gets its own metrics, in its own domain:

* **quantization**: the Allan deviation of the full-rate residual at the
  shortest τ (1, 2, 4, 8 samples), held against the gyro model's noise (before:
  the model as given; after: the pulse counter run on the model's predicted
  rate plus its white noise, simulated — a 0/1-pulse readout is not white angle
  noise of q/√12); RMS over τ of ln(measured / model). Floor: the same
  statistic of each simulated draw against the others.
* **periodic_interference**: the spectrum peak (periodic.py), **markov_bias**:
  the Allan mismatch of the bin means (gap.py); both already in ``metrics``.
* every other (deterministic) effect: the segments where its fitted signature
  stands out (segment means of its contribution over their standard errors,
  the largest ones that hold ``SHARE`` of its Σz²: ramp segments for a
  temperature effect, dwells for a rate effect), and two metrics there:

  - the **pattern amplitude** (deg/h): the GLS amplitude of the effect's
    base-projected pattern in the residual (how much of the named effect the
    residual still holds, 1 = all of it), times the RMS of the pattern's segment
    means over its segments. Before ≈ the effect's size, after ≈ 0 once it is
    fitted; the floor is E|amplitude| of noise alone (0.80σ, σ exact from the
    whitening);
  - **G1 of its segments**: G1 (gap.py) over those segments only; the floor
    is its mean on effect-free residuals through the same refit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.discrepancy.gap import Metric, SegmentGeometry
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.models.pulse_counting import PulseCounter

#: Share of an effect's Σz² over segments that its segments must hold.
SHARE = 0.9
#: Shortest averaging factors (samples) of the quantization metric.
SHORT_M = np.array([1, 2, 4, 8])
#: Most samples the short-τ Allan deviation is computed on (the start of the record).
SHORT_TAU_SAMPLES = 200_000
#: Draws of white noise for the short-τ floor.
SHORT_TAU_DRAWS = 12
#: E|x| and sd|x| of x ~ N(0, 1): the floor and spread of a pattern amplitude's magnitude.
_ABS_MEAN, _ABS_SD = math.sqrt(2.0 / math.pi), math.sqrt(1.0 - 2.0 / math.pi)


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


def pattern_metrics(effect: str, pattern: Pattern, before: Residuals, after: Residuals,
                    null_after: np.ndarray, geometry: SegmentGeometry, segment_names: list[str]
                    ) -> EffectGap:
    """The pattern amplitude and G1 over the effect's own segments (see the module docstring).

    ``null_after`` holds effect-free residuals (columns, deg/h per bin) through the final refit.
    """
    segments = effect_segments(pattern.bins_dph, geometry)
    averaging = geometry.averaging[:, segments]
    stderr = geometry.stderr_dph[segments]
    norm2 = float(pattern.white @ pattern.white)
    if not norm2 > 0:
        return EffectGap(effect, {}, "")
    c = averaging.T @ pattern.bins_dph
    rms = float(np.sqrt(np.mean(c * c)))
    sd = rms / math.sqrt(norm2)

    def amplitude_of(resid: Residuals) -> float:
        return abs(float(pattern.white @ resid.white)) / norm2 * rms

    where = _segment_kind([segment_names[k] for k in segments])
    amplitude = Metric(amplitude_of(before), amplitude_of(after), _ABS_MEAN * sd, _ABS_SD * sd, "deg/h",
                       f"{effect}: GLS amplitude of its base-projected pattern in the residual, as the "
                       f"RMS of its segment means over its {where}")
    def g1_of(resid: np.ndarray) -> np.ndarray:
        z = (averaging.T @ resid) / (stderr if resid.ndim == 1 else stderr[:, None])
        return np.mean(z**2, axis=0)

    null = g1_of(null_after)
    g1_metric = Metric(float(g1_of(before.bins_dph)), float(g1_of(after.bins_dph)), float(np.mean(null)),
                       float(np.std(null)), "1 (mean of z²)",
                       f"{effect}: G1 (segment mean over its standard error, squared, averaged) "
                       f"over its {where}")
    head = f"{effect}_pattern_dph"
    return EffectGap(effect, {head: amplitude, f"{effect}_segment_g1": g1_metric}, head)


def _short_tau_adev(resid_dph: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    result = overlapping_adev(resid_dph, fs_hz, m=SHORT_M, confidence=None)
    return result.tau_s, result.adev


def _ln_rms(adev: np.ndarray, reference: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.log(adev / reference) ** 2)))


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

    Before: against the given noise model's Allan curve (no pulse). After: against the
    mean curve of ``SHORT_TAU_DRAWS`` simulated residuals of the pulse counter run on
    the model's predicted rate (``counted_residual_dph``). Floor: the same statistic of
    each simulated draw against the mean of the others (leave one out).
    """
    n = min(len(resid_full_dph), SHORT_TAU_SAMPLES)
    resid, predicted = resid_full_dph[:n], predicted_dph[:n]
    white_dph = given.white_sigma_dph(fs_hz)
    curves = np.array([_short_tau_adev(counted_residual_dph(predicted, fs_hz, white_dph, pulse_arcsec, rng),
                                       fs_hz)[1] for _ in range(SHORT_TAU_DRAWS)])
    tau_s, measured = _short_tau_adev(resid, fs_hz)
    total = curves.sum(axis=0)
    floor = [_ln_rms(curve, (total - curve) / (len(curves) - 1)) for curve in curves]
    metric = Metric(_ln_rms(measured, given.allan_deviation_dph(tau_s)),
                    _ln_rms(measured, total / len(curves)),
                    float(np.mean(floor)), float(np.std(floor)), "1 (RMS of ln ratio)",
                    "quantization: Allan deviation of the full-rate residual at τ = 1, 2, 4, 8 samples "
                    "against the gyro model's noise (before) and against the pulse counter run on the "
                    "model's predicted rate (after), RMS over τ of ln(measured / model)")
    return EffectGap("quantization", {"quantization_short_tau_allan": metric}, "quantization_short_tau_allan")
