"""The first-order recursion y_k = a·y_{k−1} + g·x_k, compiled, bit for bit scipy's ``lfilter``.

Every Gauss-Markov process of the simulated gyro's noise (``noise.py``) and the
sensor's thermal lag (``temperature.py``) is this recursion, evaluated block by
block. ``scipy.signal.lfilter([g], [1, -a], x, zi=[a·y_prev])`` computes it in C,
but its Python wrapper costs ~13 µs a call: an IMU dry run makes ~146,000 calls
(22 flicker processes per axis, three axes, a call per process per read block),
~1.9 s of the simulated gyro's CPU for ~0.3 s of arithmetic. Importing
``scipy.signal`` also cost every process that loads the models ~0.5 s.

The compiled loop does the operations of lfilter's transposed direct form II
in its order, each rounded as there (no fused multiply-add: numba contracts
only under ``fastmath``): its delay is z = x·b₁ − y·a₁ = 0 − y·(−a), which is
the product a·y exactly, and y = z + g·x. So a dry run's samples are the same
bits as before (``tests/models/test_recursion.py`` compares with lfilter).
"""

from __future__ import annotations

import numpy as np

try:  # numba is a declared dependency; the fallback keeps the models alive if it breaks
    import numba

    @numba.njit(cache=True, nogil=True)
    def _filter(gain, a, y_prev, x, out):  # pragma: no cover - compiled
        z = a * y_prev
        for k in range(x.size):
            y = z + gain * x[k]
            out[k] = y
            z = a * y

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _filter = None
    AVAILABLE = False


def first_order(gain: float, a: float, x: np.ndarray, y_prev: float) -> np.ndarray:
    """y_k = a·y_{k−1} + gain·x_k from y_{−1} = ``y_prev`` (float64), as
    ``lfilter([gain], [1, -a], x, zi=[a * y_prev])[0]``."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if _filter is None:
        from scipy.signal import lfilter  # lazy: only without numba; its import costs ~0.5 s

        return lfilter([gain], [1.0, -a], x, zi=[a * y_prev])[0]
    out = np.empty_like(x)
    _filter(float(gain), float(a), float(y_prev), x, out)
    return out
