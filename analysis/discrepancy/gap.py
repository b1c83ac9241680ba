"""Gap metrics (model vs data, beside the noise floor) and where an unexplained remainder sits.

G1 = mean over segments of (segment-mean residual / its standard error under
the noise model)² is ≈ 1 when the model fits: it weighs each procedure step
by how well the noise lets it be measured, so a 0.1 deg/h offset means a lot
in a 20-minute soak and little in a 20-second dwell. The RMS of segment means
(deg/h) is the same thing in engineering units, the Allan mismatch compares
the residual's Allan deviation with the noise model's, and the spectrum peak
is the largest line over the noise PSD. Each metric's noise floor is its mean
over effect-free residuals drawn from the noise model and passed through the
same refit (so the fit's own absorption is in the floor too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.segments import Bins

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


def allan_mismatch(resid_bins: np.ndarray, bins: Bins, noise: NoiseModel) -> float:
    """RMS over τ of ln(residual ADEV / noise-model ADEV), τ from one bin to 1/20 of the record."""
    m = allan_taus_m(len(resid_bins))
    result = overlapping_adev(resid_bins, 1.0 / bins.width_s, m=m, confidence=None)
    model = noise.allan_deviation_dph(result.tau_s)
    return float(np.sqrt(np.mean(np.log(result.adev / model) ** 2)))


def expected_max_exponential(n: int) -> float:
    """E[max of n Exp(1)] = H_n ≈ ln n + γ: the spectrum peak of pure noise."""
    return math.log(n) + 0.5772156649 + 0.5 / n


@dataclass(frozen=True)
class Metric:
    before: float
    after: float
    noise_floor: float
    noise_spread: float
    unit: str = "1"
    description: str = ""

    def to_json(self) -> dict:
        return {"before": self.before, "after": self.after, "noise_floor": self.noise_floor,
                "unit": self.unit, "description": self.description}


def choose_primary(metrics: dict[str, Metric], found: bool) -> str:
    """The metric in which the found effect shows most: largest 'before' excess in noise spreads."""
    if not found:
        return "g1_segment_mean"

    def excess(name: str) -> float:
        m = metrics[name]
        return (m.before - m.noise_floor) / max(m.noise_spread, 1e-12)

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
