"""Own cases for the deterministic-shape test of a Markov reading (analysis/discrepancy/markov_shapes.py).

A short record whose chamber temperature goes up and comes part of the way back
(``loop_profile``: 10 min at 250 Hz, 22 → 33 °C over 5 min, a 40-s hold, down to
25 °C over 3.5 min; dwells of 6 s at ±1 … ±25 deg/s with 3 s still between, in a
new order each cycle, 60 deg/s²), and slow deterministic structure outside the
catalogue (``UNKNOWNS``), each per sample in deg/h before sizing. The numbers
are this module's own; none is taken from a held-out set's generator. The held
random walk is drawn from its own seeded generator.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import discrepancy_scenarios as scenarios
import numpy as np

FS_HZ = 250.0
DURATION_S = 600.0
#: chamber path: (time s, °C) corners, linear between them, smoothed by a 20-s moving mean
CORNERS = ((0.0, 22.0), (40.0, 22.0), (340.0, 33.0), (380.0, 33.0), (590.0, 25.0), (600.0, 25.0))
SMOOTH_S = 20.0
RATES_DPS = (1.0, 3.0, 6.0, 12.0, 25.0)
DWELL_S = 6.0
STILL_S = 3.0
ACCEL_DPS2 = 60.0


def _chamber_c(t_s: np.ndarray, fs_hz: float) -> np.ndarray:
    times, temps = zip(*CORNERS, strict=True)
    raw = np.interp(t_s, times, temps)
    k = int(SMOOTH_S * fs_hz)
    padded = np.concatenate([np.full(k, raw[0]), raw, np.full(k, raw[-1])])
    kernel = np.ones(k) / k
    return np.convolve(padded, kernel, mode="same")[k:-k]


#: the ladder profile: 9 min at 200 Hz, 24 → 31 °C over 5 min and down to 27 °C over 4; a fine
#: ladder of 3-s dwells from ±0.3 to ±6 deg/s in 0.3 deg/s steps, up and back down, signs alternating
LADDER_CORNERS = ((0.0, 24.0), (300.0, 31.0), (540.0, 27.0))
LADDER_FS_HZ = 200.0
LADDER_S = 540.0
LADDER_STEP_DPS = 0.3
LADDER_DWELL_S = 3.0
LADDER_ACCEL_DPS2 = 30.0


@functools.lru_cache(maxsize=1)
def ladder_profile() -> scenarios.Profile:
    """9 min, 200 Hz, 24 → 31 → 27 °C; a fine ladder ±0.3 … ±6 deg/s of 3-s dwells, up and down."""
    t = np.arange(int(LADDER_S * LADDER_FS_HZ)) / LADDER_FS_HZ
    times, temps = zip(*LADDER_CORNERS, strict=True)
    temp = np.interp(t, times, temps)
    rungs = np.arange(1, 21) * LADDER_STEP_DPS
    sweep = np.concatenate([rungs, rungs[::-1]])
    k = np.floor(t / LADDER_DWELL_S).astype(int)
    rate = sweep[k % sweep.size] * np.where(k % 2 == 0, 1.0, -1.0)
    return scenarios.Profile(t, scenarios._slewed(rate, LADDER_FS_HZ, LADDER_ACCEL_DPS2), temp)


@functools.lru_cache(maxsize=1)
def loop_profile() -> scenarios.Profile:
    """10 min, 250 Hz, 22 → 33 → 25 °C; 6-s dwells at ±1 … ±25 deg/s, 3 s still between."""
    t = np.arange(int(DURATION_S * FS_HZ)) / FS_HZ
    rate = np.zeros_like(t)
    rng = np.random.default_rng(8123)
    at, k = 5.0, 0
    while at + DWELL_S < DURATION_S:
        order = rng.permutation(RATES_DPS)
        for r in order:
            sign = 1.0 if k % 2 == 0 else -1.0
            rate[(t >= at) & (t < at + DWELL_S)] = sign * r
            at += DWELL_S + STILL_S
            k += 1
    return scenarios.Profile(t, scenarios._slewed(rate, FS_HZ, ACCEL_DPS2), _chamber_c(t, FS_HZ))


def _temp(p: scenarios.Profile) -> np.ndarray:
    return p.chamber_temp_c


def _time_fraction(p: scenarios.Profile) -> np.ndarray:
    return (p.t_s - p.t_s[0]) / float(p.t_s[-1] - p.t_s[0])


def _held_walk(p: scenarios.Profile, seed: int, hold_fraction: float = 0.2) -> np.ndarray:
    """A random walk held constant and refreshed every ``hold_fraction`` of the record."""
    rng = np.random.default_rng(seed + 17)
    u = _time_fraction(p)
    index = np.minimum((u / hold_fraction).astype(int), int(1.0 / hold_fraction))
    levels = np.cumsum(rng.standard_normal(index.max() + 1))
    return levels[index]


def _staircase_t(p: scenarios.Profile, step_c: float = 3.0) -> np.ndarray:
    return np.floor((_temp(p) - 20.0) / step_c)


#: name → shape(profile, seed) in deg/h before sizing
UNKNOWNS: dict[str, Callable[[scenarios.Profile, int], np.ndarray]] = {
    "bias staircase in T (a step every 3 °C)": lambda p, s: _staircase_t(p),
    "bias hinged above the mid temperature (max(0, T − T_mid))":
        lambda p, s: np.maximum(0.0, _temp(p) - 0.5 * (_temp(p).min() + _temp(p).max())),
    "scale factor on negative rates growing with T (min(ω, 0)·ΔT)":
        lambda p, s: np.minimum(p.table_rate_dps, 0.0) * (_temp(p) - _temp(p).min()),
    "logistic turn-on in time (centre 40 %, width 4 %)":
        lambda p, s: 1.0 / (1.0 + np.exp(-(_time_fraction(p) - 0.4) / 0.04)),
    "bias step at 70 % of the record": lambda p, s: (_time_fraction(p) >= 0.7).astype(float),
    "random walk held and refreshed every fifth of the record": _held_walk,
    "smooth bump in time (centre 30 %, FWHM 10 %)":
        lambda p, s: np.exp(-0.5 * ((_time_fraction(p) - 0.3) / (0.10 / 2.3548)) ** 2),
    "bias ∝ (T − T_min)³ (cubic in temperature)":
        lambda p, s: ((_temp(p) - _temp(p).min()) / max(float(np.ptp(_temp(p))), 1e-9)) ** 3,
}


def sized_unknown(name: str, p: scenarios.Profile, snr: float, seed: int, max_bins: int = 1000) -> np.ndarray:
    """The unknown's shape at known-shape SNR ``snr`` of its binned realisation (scenarios.sized_extra)."""
    return scenarios.sized_extra(UNKNOWNS[name](p, seed), snr, p, max_bins=max_bins)

