"""The first-order recursion y_k = a·y_{k−1} + g·x_k, compiled, bit for bit scipy's ``lfilter``.

Every Gauss-Markov process of the simulated gyro's noise (``noise.py``) and the
sensor's thermal lag (``temperature.py``) is this recursion, evaluated block by
block. ``scipy.signal.lfilter([g], [1, -a], x, zi=[a·y_prev])`` computes it in C,
but its Python wrapper costs ~13 µs a call: an IMU dry run makes ~146,000 calls
(22 flicker processes per axis, three axes, a call per process per read block),
~1.9 s of the simulated gyro's CPU for ~0.3 s of arithmetic. (The models no
longer import ``scipy.signal``; allantools, which the analysis imports, still does.)

The compiled loop does the operations of lfilter's transposed direct form II
in its order, each rounded as there (no fused multiply-add: numba contracts
only under ``fastmath``): its delay is z = x·b₁ − y·a₁ = 0 − y·(−a), which is
the product a·y exactly, and y = z + g·x. So a dry run's samples are the same
bits as before (``tests/models/test_recursion.py`` compares with lfilter).
"""

from __future__ import annotations

from functools import cache

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

    @numba.njit(cache=True, nogil=True)
    def _bank_sum(gains, poles, lasts, drives, out):  # pragma: no cover - compiled
        # the processes side by side, sample by sample: their recursions are independent,
        # so the core overlaps them instead of waiting on one chain's multiply-add latency
        z = poles * lasts
        y = lasts.copy()
        for k in range(out.size):
            total = 0.0
            for i in range(drives.shape[0]):
                y[i] = z[i] + gains[i] * drives[i, k]
                total += y[i]
                z[i] = poles[i] * y[i]
            out[k] = total
        lasts[:] = y

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _filter = _bank_sum = None
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


def first_order_sum(gains: np.ndarray, poles: np.ndarray, lasts: np.ndarray,
                    drives: np.ndarray) -> np.ndarray:
    """Σ_i of the recursions (gain_i, pole_i) over ``drives[i]`` from ``lasts[i]``, summed in
    row order from 0 as ``sum(first_order(...) for each row)`` adds them; ``lasts`` becomes
    each recursion's last value. One call for a bank of processes (the flicker noise's
    ~15 a block) instead of one per process and an array sum after each."""
    drives = np.ascontiguousarray(drives, dtype=np.float64)
    if _bank_sum is None:
        out = np.zeros(drives.shape[1])
        for i, row in enumerate(drives):
            y = first_order(gains[i], poles[i], row, lasts[i])
            out += y
            lasts[i] = y[-1] if y.size else lasts[i]
        return out
    out = np.empty(drives.shape[1])
    _bank_sum(gains, poles, lasts, drives, out)
    return out


@cache
def warm_up() -> None:
    """Load the compiled loops now, once per process (from numba's cache, or compiled).

    Their first call costs ~0.3 s of CPU, over a second of wall time on a loaded
    machine: inside a simulated gyro's first block it delayed the unit's answer to the
    driver's ``C`` past the driver's wall-time-bounded wait, and the run went on with
    its configuration "not confirmed" (a dry run that differed from its twin). So the
    simulator calls this when it is built, before any exchange (``gyro_sim.py``).
    """
    first_order(0.5, 0.5, np.zeros(2), 0.0)
    first_order_sum(np.ones(2), np.full(2, 0.5), np.zeros(2), np.zeros((2, 2)))
