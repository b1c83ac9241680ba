"""The one hot loop of the Allan analysis, compiled: Σ (x[i+2m] − 2x[i+m] + x[i])² for every m.

Measured on the project's 2-core machine (benchmarks/bench_allan.py), numpy
needs four passes per τ (a multiply, two adds and a dot product, even in
cache-sized chunks) and could not reach 10× allantools; a fused loop reads
each phase value once per τ and spreads the τ values over the cores. The
arithmetic per term is the same expression as allantools and as the numpy
path in ``reports/allan.py`` (kept as the fallback and as the test oracle:
both must agree to rounding), and each τ's sum is accumulated in order, so
the result does not depend on the number of threads.

numba compiles on first use and caches the machine code next to this file,
so only the very first analysis on a machine pays the ~2 s compile.
"""

from __future__ import annotations

import numpy as np

try:  # numba is a declared dependency; the fallback keeps analysis alive if it breaks
    import numba

    @numba.njit(cache=True, parallel=True, nogil=True)
    def _second_difference_sums(phase: np.ndarray, m_values: np.ndarray) -> np.ndarray:
        out = np.empty(m_values.size)
        for j in numba.prange(m_values.size):
            m = m_values[j]
            total = 0.0
            for i in range(phase.size - 2 * m):
                d = phase[i + 2 * m] - 2.0 * phase[i + m] + phase[i]
                total += d * d
            out[j] = total
        return out

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _second_difference_sums = None
    AVAILABLE = False


def second_difference_sums(phase: np.ndarray, m_values: np.ndarray) -> np.ndarray | None:
    """Σ_i (x[i+2m] − 2x[i+m] + x[i])² for each m, or None when numba is unavailable."""
    if _second_difference_sums is None:
        return None
    return _second_difference_sums(np.ascontiguousarray(phase, dtype=np.float64),
                                   np.ascontiguousarray(m_values, dtype=np.int64))
