"""Gap metrics (model vs data, beside the noise floor) and where an unexplained remainder sits.

G1 = mean over segments of (segment-mean residual / its standard error under
the noise model)² is ≈ 1 when the model fits: it weighs each procedure step
by how well the noise lets it be measured, so a 0.1 deg/h offset means a lot
in a 20-minute soak and little in a 20-second dwell. The RMS of segment means
(deg/h) is the same thing in engineering units, the Allan mismatch compares
the residual's Allan deviation with the noise model's, and the spectrum peak
is the largest line over the noise PSD.

Each metric's noise floor is a stated level, not a typical value: the level
that the metric stays at or below, under noise alone, with probability
``FLOOR_PROBABILITY`` (0.9), for residuals drawn from the noise model and
passed through the same refit (so the fit's own absorption is in the floor
too). It comes from the metric's known distribution where there is one (the
spectrum peak's max of exponentials, a G1's quadratic form in the whitened
noise) and from the simulated effect-free draws otherwise
(``order_statistic_quantile``: P(a new noise-alone value ≤ floor) ≥ 0.9). The
mean under noise alone is kept beside it (``noise_mean``). Before, the floor
was that mean, and a metric with one degree of freedom exceeds 1.5× its mean
by chance 23 % of the time (|N(0, 1)| > 1.2): a fitted effect's after-gap
"failed" on noise alone; against the 90 % level, 1.5× the floor is passed by
noise alone in 1.4 % of runs at one degree of freedom and less with more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import order_statistic_quantile
from gyrocal.analysis.discrepancy.segments import Bins

#: The probability with which noise alone keeps a metric at or below its noise floor.
FLOOR_PROBABILITY = 0.9
#: What every metric's ``noise_floor`` is, in words (results JSON ``noise_floor_definition``).
FLOOR_DEFINITION = (f"the level the metric stays at or below under noise alone (effect-free residuals "
                    f"through the same refit) with probability {FLOOR_PROBABILITY:g}")
METRIC_NAMES = ("g1_segment_mean", "segment_mean_rms_dph", "allan_mismatch", "spectrum_peak")


@dataclass(frozen=True)
class SegmentGeometry:
    """Which bins form each segment, and the standard error of each segment mean."""

    seg_of_bin: np.ndarray
    averaging: np.ndarray      # n_bins × n_segments, columns average a segment's bins
    stderr_dph: np.ndarray

    @classmethod
    def of(cls, seg_of_bin: np.ndarray, covariance: np.ndarray) -> SegmentGeometry:
        ids, inverse = np.unique(seg_of_bin, return_inverse=True)
        averaging = np.zeros((len(seg_of_bin), len(ids)))
        averaging[np.arange(len(seg_of_bin)), inverse] = 1.0
        averaging /= averaging.sum(axis=0)
        var = np.einsum("ij,ij->j", averaging, covariance @ averaging)
        return cls(inverse, averaging, np.sqrt(var))

    def means(self, resid_bins: np.ndarray) -> np.ndarray:
        return self.averaging.T @ resid_bins


def g1(geometry: SegmentGeometry, resid_bins: np.ndarray) -> np.ndarray:
    """G1 for one residual (1-D) or many (columns)."""
    z = geometry.means(resid_bins) / (geometry.stderr_dph if resid_bins.ndim == 1
                                      else geometry.stderr_dph[:, None])
    return np.mean(z**2, axis=0)


def segment_rms(geometry: SegmentGeometry, resid_bins: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(geometry.means(resid_bins) ** 2, axis=0))


def allan_taus_m(n_bins: int) -> np.ndarray:
    """One bin to 1/20 of the record: longer τ have too few averages to compare."""
    top = max(2, n_bins // 20)
    return np.unique(np.round(np.geomspace(1, top, 12)).astype(int))


def allan_log_ratio(resid_bins: np.ndarray, bins: Bins, noise: NoiseModel) -> np.ndarray:
    """ln(residual ADEV / noise-model ADEV) at each τ from one bin to 1/20 of the record."""
    m = allan_taus_m(len(resid_bins))
    result = overlapping_adev(resid_bins, 1.0 / bins.width_s, m=m, confidence=None)
    return np.log(result.adev / noise.allan_deviation_dph(result.tau_s))


def allan_mismatch(resid_bins: np.ndarray, bins: Bins, noise: NoiseModel) -> float:
    """RMS over τ of ln(residual ADEV / noise-model ADEV), τ from one bin to 1/20 of the record."""
    return float(np.sqrt(np.mean(allan_log_ratio(resid_bins, bins, noise) ** 2)))


@dataclass(frozen=True)
class AllanRatios:
    """ln(residual ADEV / noise-model ADEV) at τ = ``m`` bins: before, after, and per effect-free draw (rows).

    Computed once for the whole-record Allan mismatch; a Markov bias's own metric
    takes the τ it owns from the same numbers (own_gap.markov_metrics).
    """

    m: np.ndarray
    width_s: float
    before: np.ndarray
    after: np.ndarray
    null: np.ndarray

    @classmethod
    def of(cls, before: np.ndarray, after: np.ndarray, null_resid: np.ndarray, bins: Bins,
           noise_before: NoiseModel, noise: NoiseModel) -> AllanRatios:
        """``null_resid``: effect-free residuals (columns) through the final refit, against ``noise``."""
        return cls(allan_taus_m(len(before)), bins.width_s, allan_log_ratio(before, bins, noise_before),
                   allan_log_ratio(after, bins, noise),
                   np.array([allan_log_ratio(null_resid[:, k], bins, noise) for k in range(null_resid.shape[1])]))

    def mismatch(self) -> Metric:
        """The whole-record Allan mismatch: RMS over τ of the ratios."""
        def rms(ratios: np.ndarray) -> np.ndarray:
            return np.sqrt(np.mean(ratios**2, axis=-1))

        return Metric.of_null(float(rms(self.before)), float(rms(self.after)), rms(self.null),
                              "1 (RMS of ln ratio)", "Allan deviation of the residual's bin means against the "
                              "noise model, RMS over τ of ln(measured / model)")


def expected_max_exponential(n: int) -> float:
    """E[max of n Exp(1)] = H_n ≈ ln n + γ: the spectrum peak of pure noise."""
    return math.log(n) + 0.5772156649 + 0.5 / n


def max_exponential_quantile(n: int, level: float) -> float:
    """The ``level`` point of the max of n Exp(1): P(max ≤ x) = (1 − e^(−x))^n."""
    return -math.log(-math.expm1(math.log(level) / n))


def quadratic_form_floor(eigenvalues: np.ndarray, level: float) -> tuple[float, float, float]:
    """(``level`` point, mean, sd) of Σ λ_i·χ²₁ (Satterthwaite: a scaled χ² with its mean and variance).

    A G1 of noise alone through a linear refit is such a form (``g1_null_floor``).
    """
    lam = np.clip(np.asarray(eigenvalues, dtype=float), 0.0, None)
    s1, s2 = float(lam.sum()), float((lam**2).sum())
    if not s1 > 0:
        return 0.0, 0.0, 0.0
    scale, dof = s2 / s1, s1 * s1 / s2
    return float(scale * stats.chi2.ppf(level, dof)), s1, math.sqrt(2.0 * s2)


def g1_null_floor(geometry: SegmentGeometry, segments: np.ndarray, chol: np.ndarray, basis: np.ndarray,
                  level: float = FLOOR_PROBABILITY) -> tuple[float, float, float]:
    """(``level`` point, mean, sd) of G1 over ``segments`` for noise alone through the refit.

    Noise alone leaves r = L·(I − Q·Qᵀ)·w (w white, L the bin covariance's Cholesky
    factor, Q the refit's whitened basis), so G1 = wᵀ·Mᵀ·M·w / k with M the segment
    means over their standard errors: its distribution is fixed by the eigenvalues
    of M·Mᵀ / k, no draws needed.
    """
    seg = np.asarray(segments)
    rows = (chol.T @ geometry.averaging[:, seg]).T / geometry.stderr_dph[seg][:, None]
    rows = rows - (rows @ basis) @ basis.T
    return quadratic_form_floor(np.linalg.eigvalsh(rows @ rows.T) / len(seg), level)


@dataclass(frozen=True)
class Metric:
    """A gap metric before and after, and its noise floor (``FLOOR_DEFINITION``).

    ``noise_mean`` and ``noise_spread`` are its mean and standard deviation under
    noise alone; ``floor_probability`` the probability with which noise alone stays
    at or below ``noise_floor``.
    """

    before: float
    after: float
    noise_floor: float
    noise_spread: float
    unit: str = "1"
    description: str = ""
    noise_mean: float = math.nan
    floor_probability: float = FLOOR_PROBABILITY

    @classmethod
    def of_null(cls, before: float, after: float, null: np.ndarray, unit: str, description: str) -> Metric:
        """The metric with its floor from simulated noise-alone values (``order_statistic_quantile``)."""
        null = np.asarray(null, dtype=float)
        return cls(float(before), float(after), order_statistic_quantile(null, FLOOR_PROBABILITY),
                   float(np.std(null)), unit, description, float(np.mean(null)))

    def to_json(self) -> dict:
        return {"before": self.before, "after": self.after, "noise_floor": self.noise_floor,
                "unit": self.unit, "description": self.description,
                "noise_mean": self.noise_mean, "noise_floor_probability": self.floor_probability,
                "noise_floor_definition": FLOOR_DEFINITION}


def choose_primary(metrics: dict[str, Metric], found: bool) -> str:
    """The metric in which the found effect shows most: largest 'before' excess in noise spreads."""
    if not found:
        return "g1_segment_mean"

    def excess(name: str) -> float:
        m = metrics[name]
        mean = m.noise_mean if math.isfinite(m.noise_mean) else m.noise_floor
        return (m.before - mean) / max(m.noise_spread, 1e-12)

    return max(metrics, key=excess)


def describe_remainder(resid_bins: np.ndarray, bins: Bins, geometry: SegmentGeometry,
                       segment_names: tuple[str, ...], segment_ids: np.ndarray,
                       signals: dict[str, np.ndarray], step: tuple[float, float] | None,
                       line: tuple[float, float] | None) -> str:
    """Where the remainder sits: a step in time, the input it follows, the span it fills, a line.

    ``signals`` are binned inputs (name → values); ``step`` is (time s, size
    deg/h) of the best bias step, ``line`` (frequency Hz, amplitude deg/h) of
    a significant spectral line; either may be None.
    """
    parts: list[str] = []
    means = geometry.means(resid_bins)
    z = means / geometry.stderr_dph
    if step is not None:
        t_step, size = step
        parts.append(f"time {t_step:.0f}-{bins.centre_s[-1]:.0f} s: segment means shift by "
                      f"{size:+.3g} deg/h (a step near t = {t_step:.0f} s)")
    worst = int(np.argmax(np.abs(z)))
    in_seg = np.flatnonzero(geometry.seg_of_bin == worst)
    t0, t1 = bins.centre_s[in_seg[0]] - bins.width_s / 2, bins.centre_s[in_seg[-1]] + bins.width_s / 2
    name = segment_names[segment_ids[worst]] if len(segment_ids) > worst else str(worst)
    parts.append(f"largest in time {t0:.0f}-{t1:.0f} s ({name}): mean residual {means[worst]:+.3g} "
                 f"deg/h = {z[worst]:+.1f} standard errors")
    best_name, best_corr = None, 0.0
    for label, values in signals.items():
        seg_values = geometry.means(values)
        if np.ptp(seg_values) == 0:
            continue
        corr = float(np.corrcoef(seg_values, means)[0, 1])
        if math.isfinite(corr) and abs(corr) > abs(best_corr):
            best_name, best_corr = label, corr
    if best_name is not None:
        parts.append(f"segment means follow {best_name} most (correlation {best_corr:+.2f})")
    if line is not None:
        parts.append(f"a spectral line at {line[0]:.4g} Hz ({line[1]:.3g} deg/h)")
    return "; ".join(parts)
