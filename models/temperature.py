"""Temperature-history filters of the model: thermal lag and the hysteresis branch.

Both carry state from one block of samples to the next, and both must stay
vectorised (hours of 200 Hz data per call), so they live here as small pure
functions that take the state in and hand the new state back.
"""

from __future__ import annotations

import math

import numpy as np

from gyrocal.models.recursion import first_order

#: Band (degC) by which the chamber must move away from its last extreme
#: before the hysteresis branch flips: "rose" means T_c climbed more than
#: this above its lowest value since it last fell, "fell" means it dropped more
#: than this below its highest value since it last rose. It keeps chamber
#: control noise (~0.05 degC) from flipping the branch during soaks.
HYSTERESIS_BAND_C = 0.2

# exp(-700) is still a normal float64; chunks of the time-varying recursion are
# cut so that their cumulated decay never exceeds it.
_MAX_DECAY_PER_STEP = 500.0
_MAX_DECAY_PER_CHUNK = 200.0


def _first_order_recursion(a: np.ndarray, u: np.ndarray, x_prev: float) -> np.ndarray:
    """x_k = a_k·x_{k−1} + u_k for time-varying a (non-uniform sampling), vectorised.

    Uses x_k = P_k·(x_prev + Σ_j u_j/P_j), P_k = Π a, in chunks short enough that
    P never underflows.
    """
    decay = np.minimum(-np.log(a), _MAX_DECAY_PER_STEP)
    out = np.empty_like(u)
    start = 0
    n = len(u)
    while start < n:
        cumulated = np.cumsum(decay[start:])
        stop = start + max(1, int(np.searchsorted(cumulated, _MAX_DECAY_PER_CHUNK, side="right")))
        log_p = cumulated[: stop - start]
        p = np.exp(-log_p)
        out[start:stop] = p * (x_prev + np.cumsum(u[start:stop] * np.exp(log_p)))
        x_prev = float(out[stop - 1])
        start = stop
    return out


def thermal_lag_c(
    chamber_temp_c: np.ndarray,
    dt_s: np.ndarray | float,
    tau_s: float,
    sensor_prev_c: float | None = None,
    chamber_prev_c: float | None = None,
) -> np.ndarray:
    """Sensor temperature of dT_s/dt = (T_c − T_s)/τ, T_c linear between samples.

    The first-order-hold solution is exact for ramps (a chamber ramp at r degC/s
    gives T_s = T_c − r·τ once settled), so the lag the tests measure is the
    equation's, not a discretisation artefact:
    T_s[k] = a·T_s[k−1] + b0·T_c[k] + b1·T_c[k−1], a = e^{−dt/τ},
    b0 = 1 − τ(1−a)/dt, b1 = τ(1−a)/dt − a. With no previous sample,
    T_s(0) = T_c(0). ``dt_s[k]`` is t[k] − t[k−1] (dt_s[0] is unused without
    a previous sample).
    """
    tc = np.asarray(chamber_temp_c, dtype=float)
    n = len(tc)
    if n == 0:
        return tc.copy()
    if sensor_prev_c is None or chamber_prev_c is None:
        sensor_prev_c = chamber_prev_c = float(tc[0])
    tc_before = np.concatenate(([chamber_prev_c], tc[:-1]))
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (n,))
    uniform = np.ptp(dt) <= 1e-9 * abs(float(dt[0]))
    step = dt[:1] if uniform else dt
    one_minus_a = -np.expm1(-step / tau_s)
    a = 1.0 - one_minus_a
    b0 = 1.0 - tau_s * one_minus_a / step
    b1 = one_minus_a - b0
    u = b0 * tc + b1 * tc_before
    if uniform:
        return first_order(1.0, float(a[0]), u, sensor_prev_c)
    return _first_order_recursion(a, u, sensor_prev_c)


def temperature_rate_c_per_min(
    temp_c: np.ndarray, dt_s: np.ndarray, temp_prev_c: float | None = None
) -> np.ndarray:
    """Backward-difference dT/dt in degC/min (what `temp_rate_bias` multiplies).

    Causal, so a record evaluated in blocks gives the same values as at once:
    without a previous sample (record start) the first value is 0, which is
    also what thermal_lag gives there (T_s(0) = T_c(0)).
    """
    temp = np.asarray(temp_c, dtype=float)
    n = len(temp)
    if n == 0:
        return temp.copy()
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), (n,))
    rate = np.empty(n)
    rate[1:] = np.diff(temp) / dt[1:] * 60.0
    if temp_prev_c is not None:
        rate[0] = (temp[0] - temp_prev_c) / dt[0] * 60.0
    else:
        rate[0] = 0.0
    return rate


def hysteresis_sign(
    chamber_temp_c: np.ndarray,
    sign_prev: int = 1,
    extreme_prev_c: float | None = None,
    band_c: float = HYSTERESIS_BAND_C,
) -> tuple[np.ndarray, int, float]:
    """Branch h(t): +1 after the chamber last rose, −1 after it last fell.

    A Schmitt trigger on T_c with ``band_c`` (see :data:`HYSTERESIS_BAND_C`):
    while on the rising branch it tracks the running maximum and flips to −1
    when T_c drops ``band_c`` below it; on the falling branch it tracks the
    running minimum and flips to +1 when T_c climbs ``band_c`` above it. The
    state (branch, running extreme) comes in and goes back out, so blocks
    join exactly. Vectorised: each branch is searched in growing windows, so
    the cost is O(n) plus a little per flip.
    """
    temp = np.asarray(chamber_temp_c, dtype=float)
    n = len(temp)
    out = np.empty(n, dtype=np.int8)
    if n == 0:
        return out, sign_prev, extreme_prev_c if extreme_prev_c is not None else math.nan
    sign = 1 if sign_prev >= 0 else -1
    extreme = float(temp[0]) if extreme_prev_c is None else float(extreme_prev_c)
    i = 0
    window = 1024
    while i < n:
        segment = temp[i : i + window]
        if sign > 0:
            running = np.maximum(np.maximum.accumulate(segment), extreme)
            flips = np.flatnonzero(segment < running - band_c)
        else:
            running = np.minimum(np.minimum.accumulate(segment), extreme)
            flips = np.flatnonzero(segment > running + band_c)
        if flips.size:
            j = i + int(flips[0])
            out[i:j] = sign
            sign = -sign
            extreme = float(temp[j])
            i = j
            window = 1024
        else:
            out[i : i + len(segment)] = sign
            extreme = float(running[-1])
            i += len(segment)
            window *= 2
    return out, sign, extreme
