"""Equivalent degrees of freedom of Allan-type variances (Greenhall's algorithm).

A QA report that states an Allan deviation without its uncertainty invites
over-reading the long-τ end of the curve, where only a handful of independent
averages exist. The chi-squared confidence interval needs the *equivalent*
degrees of freedom, which depend on the noise type and on how the estimator
overlaps its terms. Greenhall & Riley ("Uncertainty of stability variances
based on finite differences", PTTI 2003; NIST SP 1065 §5.3) give an algorithm
that is exact for power-law noise; it is implemented here from the paper.

Noise types are the power-law exponent α of the *rate* (fractional-frequency)
PSD, S_y(f) ∝ f^α: +2 white angle (quantization), +1 flicker angle, 0 white
rate (angle random walk), −1 flicker rate (bias instability), −2 random walk
of rate.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats
from scipy.special import binom

ONE_SIGMA_CONFIDENCE = math.erf(1.0 / math.sqrt(2.0))  # 0.682689...

_J_MAX = 100

# Greenhall & Riley 2003, tables 1-3: rows α = +2 … −4, columns d = 1, 2, 3.
# (a0, a1) pairs; None where the variance does not converge (α + 2d ≤ 1).
_TABLE1_MODIFIED = {
    2: [(2 / 3, 1 / 3), (7 / 9, 1 / 2), (22 / 25, 2 / 3)],
    1: [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
    0: [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
    -1: [None, (1.048, 0.534), (1.180, 0.816)],
    -2: [None, (1.302, 0.535), (1.175, 0.777)],
    -3: [None, None, (1.194, 0.703)],
    -4: [None, None, (1.489, 0.702)],
}
_TABLE2_UNMODIFIED = {
    2: [(3 / 2, 1 / 2), (35 / 18, 1.0), (231 / 100, 3 / 2)],
    1: [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
    0: [(2 / 3, 1 / 6), (2 / 3, 1 / 3), (7 / 9, 1 / 2)],
    -1: [None, (0.852, 0.375), (0.997, 0.617)],
    -2: [None, (1.079, 0.368), (1.033, 0.607)],
    -3: [None, None, (1.053, 0.553)],
    -4: [None, None, (1.302, 0.535)],
}
_TABLE3_FLICKER_ANGLE = [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)]


def _table(table: dict, alpha: int, d: int) -> tuple[float, float]:
    entry = table[alpha][d - 1]
    if entry is None:
        raise ValueError(f"Greenhall table has no entry for alpha={alpha}, d={d}")
    return entry


def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Generalised autocovariance kernel of the phase for noise type α (eq. 7)."""
    t = np.asarray(t, dtype=float)
    abs_t = np.abs(t)
    power = 3 - alpha
    if alpha == 2:
        return -abs_t
    if alpha % 2 == 0:  # even α: |t|^(3-α)
        return abs_t**power
    # odd α: t^(3-α) ln|t|, zero at t = 0
    with np.errstate(divide="ignore", invalid="ignore"):
        values = t**power * np.log(abs_t)
    return np.where(abs_t == 0.0, 0.0, values)


def _sx(t: np.ndarray, filter_factor: float, alpha: int) -> np.ndarray:
    """Kernel after the averaging filter of factor F (eq. 8); F = ∞ means no averaging."""
    if math.isinf(filter_factor):
        return _sw(t, alpha + 2)
    f = float(filter_factor)
    return f * f * (2 * _sw(t, alpha) - _sw(t - 1 / f, alpha) - _sw(t + 1 / f, alpha))


def _sz(t: np.ndarray, filter_factor: float, alpha: int, d: int) -> np.ndarray:
    """Kernel after the d-th difference (eq. 9): binomial-weighted shifts of sx."""
    t = np.asarray(t, dtype=float)
    total = np.zeros_like(t)
    for k in range(-d, d + 1):
        weight = (-1) ** abs(k) * binom(2 * d, d + k)
        total = total + weight * _sx(t + k, filter_factor, alpha)
    return total


def _basic_sum(j_terms: float, m_terms: float, stride: float, filter_factor: float,
               alpha: int, d: int) -> float:
    """Eq. (10): Σ over lags of the squared normalised kernel."""
    j_int = int(j_terms)
    first = _sz(np.array([0.0]), filter_factor, alpha, d)[0] ** 2
    last = (1 - j_int / m_terms) * _sz(np.array([j_int / stride]), filter_factor, alpha, d)[0] ** 2
    lags = np.arange(1, j_int, dtype=float)
    middle = 0.0
    if lags.size:
        kernel = _sz(lags / stride, filter_factor, alpha, d)
        middle = float(np.sum(2 * (1 - lags / m_terms) * kernel**2))
    return float(first + last + middle)


def edf_greenhall(alpha: int, d: int, m: int, n_phase: int,
                  overlapping: bool = True, modified: bool = False) -> float:
    """Equivalent degrees of freedom of a difference variance estimate.

    ``alpha`` is the integer noise exponent, ``d`` the difference order (2 for
    the Allan variance), ``m`` the averaging factor (τ = m·τ0) and ``n_phase``
    the number of phase (integrated-rate) samples, i.e. rate samples + 1.
    """
    alpha = int(alpha)
    m = int(m)
    if alpha + 2 * d <= 1:
        raise ValueError(f"noise type alpha={alpha} does not converge for d={d} (need alpha+2d>1)")
    filter_factor = 1.0 if modified else float(m)
    stride = float(m) if overlapping else 1.0
    span = m / filter_factor + m * d
    if n_phase < span:
        raise ValueError(f"{n_phase} phase samples are too few for m={m}, d={d}")
    m_terms = 1 + math.floor(stride * (n_phase - span) / m)
    j_terms = min(m_terms, (d + 1) * stride)
    ratio = m_terms / stride

    if modified:
        if j_terms <= _J_MAX:
            inv = _basic_sum(j_terms, m_terms, stride, 1.0, alpha, d) / (
                _sz(np.array([0.0]), 1.0, alpha, d)[0] ** 2 * m_terms)
        elif ratio > d + 1:
            a0, a1 = _table(_TABLE1_MODIFIED, alpha, d)
            inv = (a0 - a1 / ratio) / ratio
        else:
            m_prime = _J_MAX / ratio
            inv = _basic_sum(_J_MAX, _J_MAX, m_prime, 1.0, alpha, d) / (
                _sz(np.array([0.0]), 1.0, alpha, d)[0] ** 2 * _J_MAX)
        return 1.0 / inv

    if alpha <= 0:
        if j_terms <= _J_MAX:
            f_prime = float(m) if m * (d + 1) <= _J_MAX else math.inf
            inv = _basic_sum(j_terms, m_terms, stride, f_prime, alpha, d) / (
                _sz(np.array([0.0]), f_prime, alpha, d)[0] ** 2 * m_terms)
        elif ratio > d + 1:
            a0, a1 = _table(_TABLE2_UNMODIFIED, alpha, d)
            inv = (a0 - a1 / ratio) / ratio
        else:
            m_prime = _J_MAX / ratio
            inv = _basic_sum(_J_MAX, _J_MAX, m_prime, math.inf, alpha, d) / (
                _sz(np.array([0.0]), math.inf, alpha, d)[0] ** 2 * _J_MAX)
        return 1.0 / inv

    if alpha == 1:
        if j_terms <= _J_MAX:
            inv = _basic_sum(j_terms, m_terms, stride, float(m), 1, d) / (
                _sz(np.array([0.0]), float(m), 1, d)[0] ** 2 * m_terms)
        else:
            b0, b1 = _TABLE3_FLICKER_ANGLE[d - 1]
            scale = (b0 + b1 * math.log(m)) ** 2
            if ratio > d + 1:
                a0, a1 = _table(_TABLE2_UNMODIFIED, 1, d)
                inv = (a0 - a1 / ratio) / (scale * ratio)
            else:
                m_prime = _J_MAX / ratio
                inv = _basic_sum(_J_MAX, _J_MAX, m_prime, m_prime, 1, d) / (scale * _J_MAX)
        return 1.0 / inv

    # alpha == 2 (white angle noise), unmodified.
    if math.ceil(ratio) > d:
        a0 = binom(4 * d, 2 * d) / binom(2 * d, d) ** 2
        inv = (a0 - (d / 2.0) / ratio) / m_terms
        return 1.0 / inv
    # Too few terms for the asymptotic form (τ near the record length): the
    # exact sum (eq. 10) still holds, evaluated directly.
    inv = _basic_sum(m_terms, m_terms, stride, float(m), 2, d) / (
        _sz(np.array([0.0]), float(m), 2, d)[0] ** 2 * m_terms)
    return 1.0 / inv


def chi2_interval(dev: np.ndarray, edf: np.ndarray,
                  confidence: float = ONE_SIGMA_CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided chi-squared interval of a deviation (NIST SP 1065 eq. 45)."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    dev = np.asarray(dev, dtype=float)
    edf = np.asarray(edf, dtype=float)
    tail = (1.0 - confidence) / 2.0
    chi2_low = stats.chi2.ppf(tail, edf)
    chi2_high = stats.chi2.ppf(1.0 - tail, edf)
    return dev * np.sqrt(edf / chi2_high), dev * np.sqrt(edf / chi2_low)
