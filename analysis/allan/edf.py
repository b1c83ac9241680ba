"""Equivalent degrees of freedom and chi-squared intervals of Allan-type deviations.

A QA report that states an Allan deviation without its uncertainty invites
over-reading the long-τ end of the curve, where only a handful of independent
averages exist. The chi-squared confidence interval needs the *equivalent*
degrees of freedom, which depend on the noise type and on how the estimator
overlaps its terms (Greenhall & Riley, "Uncertainty of stability variances
based on finite differences", PTTI 2003; NIST SP 1065 §5.3).

allantools implements Greenhall's algorithm and the interval, and this module
calls it. The one case it leaves out (it raises ``NotImplementedError``) is
white angle noise when an averaging time has fewer than d+1 independent terms
(for the Allan variance, τ of a quarter of the record or more; the default
τ grid stops just short of it): that case is the exact finite sum below,
and joins allantools' formula where both apply (tests/reports/test_allan_confidence.py).
Measured side by side before the hand-written port was removed (issue 27): the
EDFs of a 100-τ curve took tens of ms in either (equal to 1e-13); the interval,
one allantools call per τ, takes ~14 ms a curve against 0.4 ms vectorised, small
beside the curve itself (0.7 s at 10 M samples), so the library serves.

Noise types are the power-law exponent α of the *rate* (fractional-frequency)
PSD, S_y(f) ∝ f^α: +2 white angle (quantization), +1 flicker angle, 0 white
rate (angle random walk), −1 flicker rate (bias instability), −2 random walk
of rate.
"""

from __future__ import annotations

import math

import allantools
import numpy as np
from scipy.special import binom

ONE_SIGMA_CONFIDENCE = math.erf(1.0 / math.sqrt(2.0))  # 0.682689...


def edf_greenhall(alpha: int, d: int, m: int, n_phase: int,
                  overlapping: bool = True, modified: bool = False) -> float:
    """Equivalent degrees of freedom of a difference variance estimate.

    ``alpha`` is the integer noise exponent, ``d`` the difference order (2 for
    the Allan variance), ``m`` the averaging factor (τ = m·τ0) and ``n_phase``
    the number of phase (integrated-rate) samples, i.e. rate samples + 1.
    """
    alpha, d, m = int(alpha), int(d), int(m)
    if alpha + 2 * d <= 1:
        raise ValueError(f"noise type alpha={alpha} does not converge for d={d} (need alpha+2d>1)")
    span = (m if modified else 1) + m * d  # Greenhall's L = m/F + m·d, F = 1 or m
    if n_phase < span:
        raise ValueError(f"{n_phase} phase samples are too few for m={m}, d={d}")
    if alpha == 2 and not modified and math.ceil((n_phase - m * d) / m) <= d:
        # Fewer than d+1 independent terms (M/S ≤ d): allantools raises here.
        if not overlapping:
            raise ValueError(f"no EDF for non-overlapping white angle noise at m={m}, "
                             f"{n_phase} phase samples")
        return edf_white_angle_overlapping(d, m, n_phase)
    return float(allantools.edf_greenhall(alpha=alpha, d=d, m=m, N=int(n_phase),
                                          overlapping=overlapping, modified=modified))


def edf_white_angle_overlapping(d: int, m: int, n_phase: int) -> float:
    """EDF of the overlapping, unmodified d-th difference variance of white angle noise.

    With white phase, the d-th differences at lags that are multiples of m are
    correlated by binom(2d, d+l)/binom(2d, d) at lag l·m and not at all otherwise,
    so 1/edf = (1/M)·[1 + 2 Σ_{l=1}^{min(d, K−1)} (1 − l/r)·ρ_l²] with M terms,
    r = M/m and K = ⌈r⌉. For K > d the sum is Greenhall's closed form
    (a0 − a1/r)/M (case 4 of the paper, which allantools implements).
    """
    terms = n_phase - m * d
    if terms < 1:
        raise ValueError(f"{n_phase} phase samples are too few for m={m}, d={d}")
    ratio = terms / m
    lags = range(1, min(d, math.ceil(ratio) - 1) + 1)
    centre = binom(2 * d, d)
    total = 1.0 + 2.0 * sum((1.0 - lag / ratio) * (binom(2 * d, d + lag) / centre) ** 2
                            for lag in lags)
    return terms / total


def chi2_interval(dev: np.ndarray, edf: np.ndarray,
                  confidence: float = ONE_SIGMA_CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided chi-squared interval of each deviation (NIST SP 1065 eq. 45, via allantools)."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    dev = np.asarray(dev, dtype=float)
    edf = np.asarray(edf, dtype=float)
    bounds = [allantools.confidence_interval(float(v), float(e), confidence)
              for v, e in zip(dev.ravel(), edf.ravel(), strict=True)]
    low = np.array([b[0] for b in bounds], dtype=float).reshape(dev.shape)
    high = np.array([b[1] for b in bounds], dtype=float).reshape(dev.shape)
    return low, high
