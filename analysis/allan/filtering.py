"""Denoising filters judged by Allan variance: a diagnostic of the vendor notes' kind.

The vendor notes (seeds/003, "Soft Magnetic Error Compensation…", §2–4)
compare a Kalman filter, a Sage–Husa adaptive Kalman filter and a particle
filter by how much each reduces the Allan terms of a sensor record ("the
quantization noise and zero bias instability noise … reduced by 64 % and
66.4 %"). This module runs the first two over a log, streamed block by
block (the state carries across blocks), so ``gyrocal analyze allan LOG
--filter kalman|adaptive-kalman`` can print the terms before and after. It
never touches calibration data: it reads a log and prints numbers. (The
particle filter is left out: with the linear-Gaussian model below it
estimates what the Kalman filter computes exactly, at a cost of thousands of
particles per sample.)

The model, one state — the rate the gyro senses, deg/h, as a random walk:

    x_k = x_{k−1} + w_k,   w ~ N(0, q)          (process)
    y_k = x_k + v_k,       v ~ N(0, r)          (measurement: the logged sample)

Tuning, stated in every result:

* r, the measurement noise, is var(y_k − y_{k−1}) / 2 over the record: the
  white part of the sample-to-sample scatter, no model fit needed;
* q is set from the time constant τ_f the user asks for (``--filter-tau-s``,
  default 1 s): the steady-state gain is g = 1/(τ_f·fs), and the Riccati
  equation's steady state gives q = r·g²/(1 − g).

``kalman`` runs that filter with constant q and r (it reaches its steady
gain within a few τ_f; those first 5·τ_f of output are dropped so its
start-up transient does not pass for noise). ``adaptive-kalman`` is the
Sage–Husa filter: q as above, r re-estimated at every sample from the
innovation with the fading-memory weight d_k = (1 − b)/(1 − b^(k+1))
(forgetting factor b, ``--forgetting``, default 0.999), so the gain follows
the noise level when it changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from enum import Enum

import numpy as np

try:  # numba is a declared dependency; the fallback keeps the diagnostic alive if it breaks
    import numba

    _njit = numba.njit(cache=True, nogil=True)
except ImportError:  # pragma: no cover
    def _njit(function):
        return function


class FilterKind(str, Enum):
    KALMAN = "kalman"
    ADAPTIVE_KALMAN = "adaptive-kalman"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class FilterTuning:
    """What the filter was run with (printed and written with its result)."""

    kind: FilterKind
    tau_s: float             # the asked time constant
    rate_hz: float
    q_dph2: float            # process noise per sample, (deg/h)²
    r_dph2: float            # measurement noise (initial, for the adaptive filter), (deg/h)²
    gain: float              # steady-state gain with q and r
    forgetting: float | None  # Sage–Husa b (adaptive only)
    dropped_samples: int     # start-up transient left out of the filtered record

    def describe(self) -> str:
        model = ("state: rate (deg/h) as a random walk, x_k = x_k-1 + w (q), y_k = x_k + v (r); "
                 f"q = {self.q_dph2:.4g} (deg/h)^2 from time constant {self.tau_s:g} s, "
                 f"r = {self.r_dph2:.4g} (deg/h)^2 = var(dy)/2, steady gain {self.gain:.4g}; ")
        if self.kind is FilterKind.ADAPTIVE_KALMAN:
            model += (f"Sage-Husa: r re-estimated from the innovations, forgetting factor "
                      f"{self.forgetting:g}; ")
        return f"{self.kind} filter ({model}first {self.dropped_samples} samples dropped)"


def tune(kind: FilterKind, r_dph2: float, rate_hz: float, tau_s: float,
         forgetting: float = 0.999) -> FilterTuning:
    """q from the asked time constant, given r (see the module docstring)."""
    if not (tau_s > 0 and math.isfinite(tau_s)):
        raise ValueError(f"filter time constant must be > 0 s, got {tau_s!r}")
    if not 0.0 < forgetting < 1.0:
        raise ValueError(f"forgetting factor must lie in (0, 1), got {forgetting!r}")
    if not r_dph2 > 0:
        raise ValueError("the record has no sample-to-sample scatter to filter (var(dy) = 0)")
    gain = 1.0 / (tau_s * rate_hz)
    if gain >= 1.0:
        raise ValueError(f"a {tau_s:g} s time constant at {rate_hz:g} Hz is shorter than one "
                         "sample: nothing to filter")
    q = r_dph2 * gain * gain / (1.0 - gain)
    return FilterTuning(kind, float(tau_s), float(rate_hz), q, float(r_dph2), gain,
                        forgetting if kind is FilterKind.ADAPTIVE_KALMAN else None,
                        int(math.ceil(5.0 * tau_s * rate_hz)))


@_njit
def _kalman_block(y, out, state, q, b, adaptive):  # pragma: no cover - compiled
    """One block; ``state`` = [x, P, r, k (samples seen), started] carried across blocks."""
    x, p, r, k = state[0], state[1], state[2], state[3]
    for i in range(y.size):
        if state[4] == 0.0:
            x = y[i]
            p = r
            state[4] = 1.0
            out[i] = x
            k += 1.0
            continue
        p_minus = p + q
        innovation = y[i] - x
        if adaptive:
            d = (1.0 - b) / (1.0 - b ** (k + 1.0))
            r_new = (1.0 - d) * r + d * (innovation * innovation - p_minus)
            r = r_new if r_new > 1e-3 * state[5] else 1e-3 * state[5]
        gain = p_minus / (p_minus + r)
        x = x + gain * innovation
        p = (1.0 - gain) * p_minus
        out[i] = x
        k += 1.0
    state[0], state[1], state[2], state[3] = x, p, r, k


def filtered_blocks(blocks: Callable[[], Iterable[np.ndarray]], tuning: FilterTuning
                    ) -> Callable[[], Iterator[np.ndarray]]:
    """A re-iterable of the filtered record (each call restarts the filter), transient dropped."""
    adaptive = tuning.kind is FilterKind.ADAPTIVE_KALMAN
    b = tuning.forgetting if tuning.forgetting is not None else 0.0

    def run() -> Iterator[np.ndarray]:
        state = np.array([0.0, 0.0, tuning.r_dph2, 0.0, 0.0, tuning.r_dph2])
        to_drop = tuning.dropped_samples
        for block in blocks():
            y = np.ascontiguousarray(block, dtype=np.float64)
            out = np.empty_like(y)
            _kalman_block(y, out, state, tuning.q_dph2, b, adaptive)
            if to_drop:
                cut = min(to_drop, out.size)
                out, to_drop = out[cut:], to_drop - cut
            if out.size:
                yield out
    return run


def difference_variance(blocks: Callable[[], Iterable[np.ndarray]]) -> float:
    """var(y_k − y_{k−1}) / 2 over the record (blocks joined): the filter's r."""
    total, total2, count = 0.0, 0.0, 0
    last = None
    for block in blocks():
        y = np.asarray(block, dtype=np.float64)
        if y.size == 0:
            continue
        d = np.diff(y) if last is None else np.diff(np.concatenate(([last], y)))
        total += float(d.sum())
        total2 += float(np.dot(d, d))
        count += d.size
        last = y[-1]
    if count < 2:
        raise ValueError("a record of fewer than 3 samples cannot be filtered")
    mean = total / count
    return (total2 / count - mean * mean) * count / (count - 1) / 2.0


def reduction_pct(before: float, after: float) -> float | None:
    """How much a term fell, % of its value before (negative: it grew); None if it was 0."""
    return None if before <= 0 else (before - after) / before * 100.0
