"""Dominant power-law noise type at each averaging time (lag-1 autocorrelation).

The EDF of an Allan deviation depends on the noise type, and a gyro's type
changes along the curve (quantization at short τ, angle random walk, bias
instability, rate random walk at long τ). Riley & Greenhall ("Power law noise
identification using the lag 1 autocorrelation", 2004; NIST SP 1065 §5.6)
identify it from the lag-1 autocorrelation of the rate averaged over τ: white
rate noise has r1 ≈ 0, each differencing step shifts α by 2.

Documented choices (departures from the textbook procedure):

- At most ``max_points`` averages (the first ones) are used per τ. Identifying
  a type needs a few hundred points, not ten million, and this keeps the
  10 M-sample analysis O(N) in time and memory.
- The method needs ≥ 30 averages; at longer τ the type found at the longest
  identifiable τ is carried forward (the curve rarely changes type in the
  last factor of a few before the record length).
- Types are clamped to the range the Allan variance converges for, α ∈ [−2, +2]
  (a rate ramp shows up as −2: its EDF is then that of rate random walk).

Why not ``allantools.autocorr_noise_id``: it is the same method (and the tests'
oracle, type for type), but its lag-1 autocorrelation is a Python loop over the
samples; ``benchmarks/bench_noise_id.py`` measures it 83x (1 M samples) to 184x
(10 M) slower on the same averages, with the same type at every τ (README,
"Measured figures"): seconds to tens of seconds a curve, more than the curve itself.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from threadpoolctl import ThreadpoolController

MIN_POINTS = 30
ALPHA_MIN = -2
ALPHA_MAX = 2


def lag1_autocorrelation(z: np.ndarray) -> float:
    """Lag-1 autocorrelation about the mean (Riley & Greenhall eq. 2)."""
    centred = z - z.mean()
    denominator = float(np.dot(centred, centred))
    if denominator == 0.0:
        return 0.0
    return float(np.dot(centred[:-1], centred[1:])) / denominator


def _detrend_linear(z: np.ndarray) -> np.ndarray:
    """Remove a least-squares line: a rate ramp would otherwise dominate r1."""
    t = np.arange(z.size, dtype=float)
    t -= t.mean()
    slope = float(np.dot(t, z - z.mean())) / float(np.dot(t, t))
    return z - z.mean() - slope * t


def identify_alpha_from_averages(averages: np.ndarray, d_max: int = 2) -> int | None:
    """Integer α of the rate PSD from τ-averaged rate values; None when too few."""
    if averages.size < MIN_POINTS:
        return None
    z = _detrend_linear(np.asarray(averages, dtype=float))
    d = 0
    while True:
        r1 = lag1_autocorrelation(z)
        rho = r1 / (1.0 + r1)
        if rho < 0.25 or d >= d_max:
            alpha = int(-np.round(2.0 * rho) - 2 * d)
            return int(np.clip(alpha, ALPHA_MIN, ALPHA_MAX))
        z = np.diff(z)
        d += 1


def identify_alpha_per_m(phase: np.ndarray, m_values: np.ndarray,
                         max_points: int = 100_000) -> np.ndarray:
    """α for each averaging factor, from the phase (cumulative rate) samples.

    Non-overlapping τ-averages come straight from the phase:
    ȳ_k = (x[(k+1)m] − x[km]) / (m·τ0); the τ0 factor does not change r1.
    """
    n_rate = phase.size - 1
    decimated = [phase[: min(n_rate // int(m), max_points) * int(m) + 1 : int(m)]
                 for m in m_values]
    return alpha_per_m_from_decimated(decimated)


@cache
def _blas() -> ThreadpoolController:
    """The loaded BLAS libraries, found once (a search costs ~10 ms, every curve needs it)."""
    return ThreadpoolController()


def alpha_per_m_from_decimated(decimated: list[np.ndarray]) -> np.ndarray:
    """α per τ from the decimated phase x[0], x[m], x[2m], … of each averaging factor.

    The streaming Allan pass (:mod:`gyrocal.analysis.allan.stream`) collects
    these points on its way through the record, so a record that does not fit
    in memory is identified exactly as an in-memory one.
    """
    # One BLAS thread: the dot products here are 10^5 long, where a threaded
    # OpenBLAS only contends (1 M samples on a loaded 2-core machine: 0.5-4 s
    # threaded, 0.04 s single; bench_noise_id.py).
    with _blas().limit(limits=1, user_api="blas"):
        identified = [identify_alpha_from_averages(np.diff(points))
                      if points.size - 1 >= MIN_POINTS else None for points in decimated]
    alphas = np.empty(len(decimated), dtype=int)
    last_known: int | None = None
    pending: list[int] = []
    for index, alpha in enumerate(identified):
        if alpha is None:
            if last_known is None:
                pending.append(index)
                continue
            alpha = last_known
        alphas[index] = alpha
        last_known = alpha
    # Only reachable when not even the first τ had 30 averages: assume white rate.
    for index in pending:
        alphas[index] = last_known if last_known is not None else 0
    return alphas
