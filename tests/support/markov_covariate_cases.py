"""Own cases for the Markov-covariate test (analysis/discrepancy/markov_covariates.py): known truth.

A short, fast-sampled record with a thermal shock (``shock_profile``: 15 min at
400 Hz, setpoints 25 → 60 → 5 °C followed by the air with a critically damped
75-s response, a block of rate rungs and a full turn every 100 s), and slow
structure outside the catalogue tied to what the rig logs (``UNKNOWNS``), each
per sample in deg/h before sizing. The numbers are this module's own; none is
taken from a held-out set's generator. The random shapes (a random walk while
turning, a Gauss–Markov bias whose σ grows with temperature) are drawn from
their own seeded generator.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import discrepancy_scenarios as scenarios
import numpy as np

FS_HZ = 400.0
DURATION_S = 900.0
#: setpoint steps (time s, °C); the air follows each with a critically damped response
SETPOINTS = ((0.0, 25.0), (140.0, 60.0), (470.0, 5.0))
AIR_TAU_S = 75.0
#: rungs (deg/s) of 5 s each, in a new order every block, signs alternating; a static hold first
RUNGS_DPS = (0.5, 2.0, 8.0, 25.0, 60.0, 150.0)
BLOCK_S = 100.0
STATIC_S = 25.0
RUNG_S = 5.0
TURN_DPS = 12.0
ACCEL_DPS2 = 200.0
#: below this |rate| (deg/s) the table is taken as still
STILL_DPS = 0.05


def _air_temp_c(t_s: np.ndarray) -> np.ndarray:
    temp = np.full_like(t_s, SETPOINTS[0][1])
    for (t0, _), (t1, target) in zip(SETPOINTS[:-1], SETPOINTS[1:], strict=True):
        del t0
        after = t_s >= t1
        u = (t_s[after] - t1) / AIR_TAU_S
        start = temp[after]
        temp[after] = target + (start - target) * (1.0 + u) * np.exp(-u)
    return temp


@functools.lru_cache(maxsize=1)
def shock_profile() -> scenarios.Profile:
    """15 min, 400 Hz, 25 → 60 → 5 °C thermal shock; rungs of 5 s and a 12 deg/s turn each 100 s."""
    t = np.arange(int(DURATION_S * FS_HZ)) / FS_HZ
    rate = np.zeros_like(t)
    rng = np.random.default_rng(4711)
    for block, start in enumerate(np.arange(0.0, DURATION_S - BLOCK_S + 1.0, BLOCK_S)):
        at = start + STATIC_S
        for k, rung in enumerate(rng.permutation(RUNGS_DPS)):
            sign = 1.0 if (k + block) % 2 == 0 else -1.0
            rate[(t >= at) & (t < at + RUNG_S)] = sign * rung
            at += RUNG_S
        turn_s = 360.0 / TURN_DPS
        rate[(t >= at + 5.0) & (t < at + 5.0 + turn_s)] = TURN_DPS
    return scenarios.Profile(t, scenarios._slewed(rate, FS_HZ, ACCEL_DPS2), _air_temp_c(t))


def _angle_deg(p: scenarios.Profile) -> np.ndarray:
    return np.cumsum(p.table_rate_dps) / p.fs_hz


def _turning(p: scenarios.Profile) -> np.ndarray:
    return (np.abs(p.table_rate_dps) > STILL_DPS).astype(float)


def _second_difference(p: scenarios.Profile) -> np.ndarray:
    """d²T/dt² of the chamber air (°C/min²), from one-second samples, back at the full rate."""
    t1 = np.arange(0.0, p.t_s[-1] + 1.0, 1.0)
    temp = np.interp(t1, p.t_s, p.chamber_temp_c)
    d2 = np.gradient(np.gradient(temp, t1), t1) * 3600.0
    return np.interp(p.t_s, t1, d2)


def _second_axis(p: scenarios.Profile) -> np.ndarray:
    """An unlogged second axis indexed four times: Earth-rate level steps and 7-s coupled pulses."""
    times_s = (160.0, 355.0, 590.0, 760.0)
    levels = (1.0, -0.7, 0.45, -1.1)
    out = np.zeros_like(p.t_s)
    for at, level in zip(times_s, levels, strict=True):
        out[p.t_s >= at] = level
        inside = (p.t_s >= at - 7.0) & (p.t_s < at)
        out[inside] += 2.2 * np.sin(math.pi * (p.t_s[inside] - at + 7.0) / 7.0)
    return out


def _walk_while_turning(p: scenarios.Profile, seed: int) -> np.ndarray:
    """A random walk whose increments come only while the table turns (one-second steps)."""
    rng = np.random.default_rng(seed)
    t1 = np.arange(0.0, p.t_s[-1] + 1.0, 1.0)
    turning = np.interp(t1, p.t_s, _turning(p))
    walk = np.cumsum(turning * rng.standard_normal(t1.size))
    return np.interp(p.t_s, t1, walk)


def _markov_growing_with_temperature(p: scenarios.Profile, seed: int, tau_s: float = 20.0) -> np.ndarray:
    """A Gauss–Markov bias (τ 20 s) whose σ grows from 0.15 to 1 over the chamber's span."""
    rng = np.random.default_rng(seed)
    t1 = np.arange(0.0, p.t_s[-1] + 1.0, 1.0)
    phi = math.exp(-1.0 / tau_s)
    drive = math.sqrt(1.0 - phi * phi) * rng.standard_normal(t1.size)
    x = np.empty(t1.size)
    x[0] = rng.standard_normal()
    for k in range(1, t1.size):
        x[k] = phi * x[k - 1] + drive[k]
    temp = np.interp(t1, p.t_s, p.chamber_temp_c)
    span = (temp - temp.min()) / max(float(temp.max() - temp.min()), 1e-9)
    return np.interp(p.t_s, t1, x * (0.15 + 0.85 * span))


#: name → shape(profile, seed) in deg/h before sizing
UNKNOWNS: dict[str, Callable[[scenarios.Profile, int], np.ndarray]] = {
    "bias ∝ d²T/dt²": lambda p, s: _second_difference(p),
    "offset while the table turns": lambda p, s: _turning(p),
    "random walk advancing only while turning": _walk_while_turning,
    "Gauss–Markov bias whose σ grows with temperature": _markov_growing_with_temperature,
    "bias in the 200–215° sector of the table angle":
        lambda p, s: ((np.mod(_angle_deg(p), 360.0) >= 200.0) & (np.mod(_angle_deg(p), 360.0) < 215.0))
        .astype(float),
    "unlogged second axis indexed four times (levels + pulses)": lambda p, s: _second_axis(p),
    "vibration rectified near 40 deg/s (Lorentzian in |ω|)":
        lambda p, s: 1.0 / (1.0 + ((np.abs(p.table_rate_dps) - 40.0) / 12.0) ** 2),
}


def sized_unknown(name: str, p: scenarios.Profile, snr: float, seed: int, max_bins: int = 1000) -> np.ndarray:
    """The unknown's shape at known-shape SNR ``snr`` of its binned realisation (scenarios.sized_extra)."""
    return scenarios.sized_extra(UNKNOWNS[name](p, seed), snr, p, max_bins=max_bins)
