"""The hot loops of the Allan analysis, compiled: Σ (x[i+2m] − 2x[i+m] + x[i])² for every m.

The estimator is memory-bound: each τ touches every phase value. Measured on
the project's 2-core machine (benchmarks/bench_allan.py), numpy needs four
passes per τ and could not reach 10× allantools. These kernels read the
phase in *tiles* of :data:`TILE` samples: one tile of x[i] stays in cache
while every τ is evaluated over it, so the x[i] stream is read once for all
τ instead of once per τ, and for m below a tile the x[i+m] and x[i+2m] reads
hit the same cache lines too. Tiles are spread over the cores.

Determinism and exactness: each tile's partial sum is accumulated in index
order, and the partial sums are added to the running total in tile order
after the parallel part. The result therefore does not depend on the number
of threads, and — because tiles are aligned to global sample indices — it is
bit-for-bit the same whether the phase is one array in memory or streamed
block by block from disk (:mod:`gyrocal.analysis.allan.stream`), as long as
blocks are whole tiles. The arithmetic per term is the same expression as
allantools and as the numpy oracle in ``analysis/allan/deviation.py``.

numba compiles on first use and caches the machine code next to this file,
so only the very first analysis on a machine pays the ~2 s compile.
"""

from __future__ import annotations

import numpy as np

#: Samples per tile: 32 KiB of float64, so a tile of x[i] and its neighbours stay in L1/L2.
TILE = 4096

try:  # numba is a declared dependency; the fallback keeps analysis alive if it breaks
    import numba

    # Reassociation lets LLVM keep several SIMD partial sums in flight: measured
    # 0.26 ns per term against 0.91 for one running sum (the add latency bound).
    # The order is fixed by the compiled code, and both kernels below call this
    # one function on the same array types, so their results stay identical.
    @numba.njit(cache=True, nogil=True, fastmath={"reassoc", "nsz", "arcp", "contract"})
    def _run_sum(a, b, c):  # pragma: no cover - compiled
        s = 0.0
        for k in range(a.size):
            d = c[k] - 2.0 * b[k] + a[k]
            s += d * d
        return s

    @numba.njit(cache=True, parallel=True, nogil=True)
    def _window_sums(window, counts, m_values, totals):  # pragma: no cover - compiled
        n_tiles = (counts.max() + TILE - 1) // TILE if counts.size else 0
        partial = np.zeros((n_tiles, m_values.size))
        for t in numba.prange(n_tiles):
            lo = t * TILE
            for j in range(m_values.size):
                hi = min(lo + TILE, counts[j])
                if hi > lo:
                    m = m_values[j]
                    partial[t, j] = _run_sum(window[lo:hi], window[lo + m : hi + m],
                                             window[lo + 2 * m : hi + 2 * m])
        for t in range(n_tiles):
            for j in range(m_values.size):
                if t * TILE < counts[j]:
                    totals[j] += partial[t, j]

    @numba.njit(cache=True, parallel=True, nogil=True)
    def _three_stream_sum(a, b, c, count, total):  # pragma: no cover - compiled
        n_tiles = (count + TILE - 1) // TILE
        partial = np.zeros(n_tiles)
        for t in numba.prange(n_tiles):
            lo = t * TILE
            hi = min(lo + TILE, count)
            partial[t] = _run_sum(a[lo:hi], b[lo:hi], c[lo:hi])
        for t in range(n_tiles):
            total += partial[t]
        return total

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _window_sums = None
    _three_stream_sum = None
    AVAILABLE = False


def _tile_sums_numpy(d: np.ndarray) -> np.ndarray:
    """Per-tile Σ d² of a second-difference run that starts on a tile boundary."""
    full = (d.size // TILE) * TILE
    sums = np.einsum("ij,ij->i", d[:full].reshape(-1, TILE), d[:full].reshape(-1, TILE))
    if full < d.size:
        sums = np.append(sums, float(np.dot(d[full:], d[full:])))
    return sums


def _window_sums_numpy(window, counts, m_values, totals) -> None:
    """Fallback without numba: the same tiles, added to the total in the same order."""
    for j, m in enumerate(m_values):
        m, count = int(m), int(counts[j])
        for start in range(0, count, 64 * TILE):
            stop = min(start + 64 * TILE, count)
            d = window[start + 2 * m : stop + 2 * m] - 2.0 * window[start + m : stop + m]
            d += window[start:stop]
            for value in _tile_sums_numpy(d):
                totals[j] += value


def window_sums(window: np.ndarray, counts: np.ndarray, m_values: np.ndarray,
                totals: np.ndarray, compiled: bool = True) -> None:
    """Add Σ_{i<counts[j]} (w[i+2m] − 2w[i+m] + w[i])², m = m_values[j], to ``totals[j]``.

    ``window`` starts at a tile-aligned global index; ``counts[j]`` is how
    many second differences of m_values[j] start inside this block (the
    caller clips it at the record's end). ``totals`` is updated in place,
    tile by tile in order.
    """
    window = np.ascontiguousarray(window, dtype=np.float64)
    counts = np.ascontiguousarray(counts, dtype=np.int64)
    m_values = np.ascontiguousarray(m_values, dtype=np.int64)
    if counts.size and counts.max() > 0:
        needed = int(np.max(np.where(counts > 0, counts + 2 * m_values, 0)))
        if needed > window.size:
            raise ValueError(f"window of {window.size} samples, the sums need {needed}")
    if compiled and _window_sums is not None:
        _window_sums(window, counts, m_values, totals)
    else:
        _window_sums_numpy(window, counts, m_values, totals)


def three_stream_sum(a: np.ndarray, b: np.ndarray, c: np.ndarray, count: int, total: float,
                     compiled: bool = True) -> float:
    """``total`` plus Σ_{i<count} (c[i] − 2b[i] + a[i])², tile by tile in order.

    a, b, c are x[s…], x[s+m…], x[s+2m…] of one block: the long-τ case, where
    the three reads lie too far apart to share one window in memory.
    """
    if compiled and _three_stream_sum is not None:
        return float(_three_stream_sum(a, b, c, int(count), float(total)))
    d = c[:count] - 2.0 * b[:count] + a[:count]
    for value in _tile_sums_numpy(d):
        total += float(value)
    return float(total)
