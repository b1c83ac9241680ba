"""A second held-out validation set for the discrepancy workflow (issue 29): profiles S1–S3, new unknowns.

The first held-out set (R1–R3, ``discrepancy_fresh``) has been run and read
while the workflow was being changed, so it no longer holds anything out. This
set was made apart from that work, by the same rule (``discrepancy_heldout``),
and is meant to be run against the workflow, not tuned on:

* three procedures unlike P1–P3, Q1–Q3 and R1–R3 (``PROFILES``): S1, 13 min at
  1000 Hz, two-point cold/hot soaks (−15 and 55 °C) joined by 20 °C/min
  ramps, a fine rate ladder ±0.1…300 deg/s climbed in the cold soak and
  descended in the hot one; S2, 100 min at 25 Hz, one slow linear ramp
  0 → 50 °C across the record, the table only in continuous rate sweeps
  ±250 deg/s (no dwells); S3, 20 h at 2.5 Hz, a temperature cycle with plateaus
  at 25, 65 and −25 °C and ramps of 1, 1.5 and 0.5 °C/min, rates only in the
  plateaus (a ladder up and back down, ±0.5…250 deg/s);
* families of structure outside the catalogue that no earlier set had
  (``UNKNOWN``): a Shupe-like bias whose coefficient grows with temperature
  (∝ ΔT·dT/dt), a scale factor with hysteresis in rate (by whether the dwell
  was reached from a lower or a higher rate), a scale factor settling after
  each rate change, a bias re-drawn at each power cycle, a slow sine bias of
  period longer than the record, intermittent noise bursts, a noise level
  growing with temperature, a line whose frequency drifts with time, a bias in
  the log of the time since the temperature path last changed, an asymmetric
  telegraph bias, excess noise with a f^−1.5 power spectrum, and three
  combinations of a catalogue effect with one of them.

Sizes: 10σ by the rule of ``discrepancy_heldout`` (known-shape SNR of the
binned shape, norm against the white noise for a line, expected likelihood
ratio for a noise-level change). Runs are seeded 19000 + … (apart from R's
9000 + …).
"""

from __future__ import annotations

import math

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_heldout import FreshProfile, HeldOutSet, Unknown, scheduled_profile

S1_KNOTS = ((0.0, 25.0), (60.0, 25.0), (180.0, -15.0), (390.0, -15.0), (600.0, 55.0), (780.0, 55.0))
S1_LADDER_DPS = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 300.0)


def _ladder(levels_dps: tuple[float, ...], dwell_s: float) -> tuple[tuple[float, float], ...]:
    """Each level +r then −r for ``dwell_s`` each, in the order given."""
    return tuple((sign * r, dwell_s) for r in levels_dps for sign in (1.0, -1.0))


def _path(knots: tuple[tuple[float, float], ...]):
    times, temps = np.array(knots).T
    return lambda t: np.interp(t, times, temps)


def _s1() -> scenarios.Profile:
    """13 min at 1000 Hz: 1 min at 25 °C, 20 °C/min down to a 3.5-minute −15 °C soak, 20 °C/min up to a
    3-minute 55 °C soak.

    The rate ladder (6-s dwells, 200 deg/s²) climbs ±0.1 … 300 deg/s in the
    cold soak and comes back down in the hot one, so a rate's history differs
    between the two temperatures.
    """
    up, down = _ladder(S1_LADDER_DPS, 6.0), _ladder(S1_LADDER_DPS[::-1], 6.0)
    cold = scheduled_profile(780.0, 1000.0, _path(S1_KNOTS), up, (200.0,), 200.0)
    hot = scheduled_profile(780.0, 1000.0, _path(S1_KNOTS), down, (615.0,), 200.0)
    return scenarios.Profile(cold.t_s, cold.table_rate_dps + hot.table_rate_dps, cold.chamber_temp_c)


S2_KNOTS = ((0.0, 0.0), (300.0, 0.0), (5700.0, 50.0), (6000.0, 50.0))
S2_SWEEP_DPS, S2_SWEEP_DPS2 = 250.0, 2.0
S2_SWEEP_STARTS_S = (150.0, 1140.0, 2130.0, 3120.0, 4110.0, 5100.0)


def _s2() -> scenarios.Profile:
    """100 min at 25 Hz: 5 min at 0 °C, one 0.556 °C/min ramp to 50 °C, 5 min at 50 °C.

    The table only sweeps: every 16.5 minutes 0 → +250 → −250 → 0 deg/s at a
    constant 2 deg/s² (500 s), still in between; no rate is ever held.
    """
    t = np.arange(int(round(6000.0 * 25.0))) / 25.0
    leg_s = S2_SWEEP_DPS / S2_SWEEP_DPS2
    rate = np.zeros_like(t)
    for i, start in enumerate(S2_SWEEP_STARTS_S):
        sign = 1.0 if i % 2 == 0 else -1.0          # every other sweep goes the other way first
        knots_s = start + np.array([0.0, leg_s, 3.0 * leg_s, 4.0 * leg_s])
        inside = (t >= knots_s[0]) & (t <= knots_s[-1])
        rate[inside] = np.interp(t[inside], knots_s, sign * S2_SWEEP_DPS * np.array([0.0, 1.0, -1.0, 0.0]))
    return scenarios.Profile(t, rate, _path(S2_KNOTS)(t))


def s3_knots() -> tuple[tuple[float, float], ...]:
    """A 500-minute cycle, 2.4 times: 25 °C 60 min, 1 °C/min to 65 °C, 120 min, 1.5 °C/min to −25 °C,
    120 min, 0.5 °C/min back to 25 °C."""
    cycle_min = ((0.0, 25.0), (60.0, 25.0), (100.0, 65.0), (220.0, 65.0), (280.0, -25.0), (400.0, -25.0))
    knots = [(60.0 * (500.0 * k + m), c) for k in range(3) for m, c in cycle_min]
    return tuple((s, c) for s, c in knots if s <= 72000.0) + ((72000.0, 65.0),)


S3_LADDER_DPS = (0.5, 2.0, 8.0, 25.0, 80.0, 250.0)


def s3_plateau_starts_s() -> tuple[float, ...]:
    """Start of every plateau of ``s3_knots`` (a knot followed by one at the same temperature)."""
    knots = s3_knots()
    return tuple(a[0] for a, b in zip(knots[:-1], knots[1:], strict=True) if a[1] == b[1] and b[0] - a[0] >= 3600.0)


def _s3() -> scenarios.Profile:
    """20 h at 2.5 Hz on ``s3_knots``: 20 minutes into each plateau a 33-minute ladder, nothing elsewhere.

    The ladder climbs ±0.5 … 250 deg/s and comes back down (90-s dwells,
    50 deg/s²): the same rates reached from below and from above.
    """
    ladder = _ladder(S3_LADDER_DPS + S3_LADDER_DPS[-2::-1], 90.0)
    return scheduled_profile(72000.0, 2.5, _path(s3_knots()), ladder,
                             tuple(s + 1200.0 for s in s3_plateau_starts_s()), 50.0)


# --- structure outside the catalogue -------------------------------------------------------------

def _slope_c_per_min(p: scenarios.Profile) -> np.ndarray:
    return np.gradient(p.chamber_temp_c, p.t_s) * 60.0


def _shupe_in_temperature(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A dT/dt bias whose coefficient grows with temperature: ΔT·dT/dt (ΔT from 25 °C)."""
    return (p.chamber_temp_c - 25.0) * _slope_c_per_min(p)


def _held_since(changed: np.ndarray) -> np.ndarray:
    """Index of the last sample at or before each sample where ``changed`` is true (0 before any)."""
    return np.maximum.accumulate(np.where(changed, np.arange(changed.size), 0))


def _dwell_levels(p: scenarios.Profile) -> np.ndarray:
    """|ω| of the last constant non-zero dwell (≥ 1 s held), carried through slews and statics; 0 before any."""
    rate = p.table_rate_dps
    steady = np.concatenate([[False], np.diff(rate) == 0.0]) & (rate != 0.0)
    run = np.convolve(steady, np.ones(max(1, int(p.fs_hz))), mode="full")[: rate.size] >= max(1, int(p.fs_hz))
    held = np.abs(rate)[_held_since(run)]
    return np.where(run[_held_since(run)], held, 0.0)


def _sf_rate_hysteresis(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·h: h = +1 while the dwell level was reached from a lower |ω|, −1 from a higher one (held at equal)."""
    level = _dwell_levels(p)
    step = np.sign(np.diff(level, prepend=level[0]))
    step[level == 0.0] = 0.0
    h = step[_held_since(step != 0.0)]
    return p.table_rate_dps * np.where(h == 0.0, 1.0, h)


def _sf_settling(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·exp(−(time since the rate last changed)/4 s): a scale factor settling after each change."""
    changed = np.concatenate([[True], np.diff(p.table_rate_dps) != 0.0])
    since_s = p.t_s - p.t_s[_held_since(changed)]
    return p.table_rate_dps * np.exp(-since_s / 4.0)


POWER_CYCLES = (0.17, 0.38, 0.55, 0.81)    # fractions of the record


def _power_cycles(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A bias level drawn afresh (standard normal) at each power cycle; the first segment at 0."""
    segment = np.searchsorted(np.array(POWER_CYCLES) * p.t_s[-1], p.t_s, side="right")
    levels = np.concatenate([[0.0], rng.standard_normal(len(POWER_CYCLES))])
    return levels[segment]


def _slow_sine(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A bias sine of period 1.6 × the record (a daily-like swing the record sees a part of)."""
    return np.sin(2.0 * math.pi * p.t_s / (1.6 * p.t_s[-1]) + 0.9)


def _noise_bursts(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Relative variance 1 in bursts of 0.4 % of the record at exponential intervals (mean 8 %)."""
    span = p.t_s[-1]
    starts = np.cumsum(rng.exponential(0.08 * span, size=40))
    inside = np.zeros(p.t_s.size, dtype=bool)
    for start in starts[starts < span]:
        inside |= (p.t_s >= start) & (p.t_s < start + 0.004 * span)
    return inside.astype(float)


def _noise_with_temperature(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Relative variance increase growing linearly from the coldest to the hottest point of the record."""
    temp = p.chamber_temp_c
    return (temp - temp.min()) / (temp.max() - temp.min())


def _chirp(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A line at 0.21·fs (at most 91.7 Hz) whose frequency rises by 3 % over the record."""
    f0 = min(0.21 * p.fs_hz, 91.7)
    freq = f0 * (1.0 + 0.03 * p.t_s / p.t_s[-1])
    return np.sin(2.0 * math.pi * np.cumsum(freq) / p.fs_hz)


def _log_since_temperature_change(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """log(1 + s/60) of the seconds s since the temperature path last changed slope (a soak began or ended)."""
    slope = _slope_c_per_min(p)
    changed = np.concatenate([[True], np.abs(np.diff(slope)) > 1e-6])
    return np.log1p((p.t_s - p.t_s[_held_since(changed)]) / 60.0)


def _asymmetric_telegraph(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """0/1 switching: mean dwell 1 % of the record at 1, 8 % at 0 (popcorn with unequal states)."""
    span, at, switches = p.t_s[-1], 0.0, []
    while at < span:
        at += rng.exponential((0.08 if len(switches) % 2 == 0 else 0.01) * span)
        switches.append(at)
    return (np.searchsorted(np.array(switches), p.t_s) % 2).astype(float)


def _excess_f15(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Noise with a f^−1.5 power spectrum (amplitude ∝ f^−0.75), between flicker and random walk."""
    spectrum = np.fft.rfft(rng.standard_normal(p.t_s.size))
    f = np.fft.rfftfreq(p.t_s.size, 1.0 / p.fs_hz)
    spectrum[0] = 0.0
    spectrum[1:] /= f[1:] ** 0.75
    return np.fft.irfft(spectrum, n=p.t_s.size)


SHUPE_T = "bias ∝ ΔT·dT/dt (a dT/dt coefficient growing with temperature)"
SF_HYSTERESIS = "scale factor by whether the dwell rate was reached from below or above"
SF_SETTLING = "scale factor settling after each rate change (τ 4 s)"
SLOW_SINE = "bias on a sine of period 1.6 × the record"

UNKNOWN: dict[str, Unknown] = {
    SHUPE_T: Unknown(_shupe_in_temperature),
    SF_HYSTERESIS: Unknown(_sf_rate_hysteresis),
    SF_SETTLING: Unknown(_sf_settling),
    "bias re-drawn at each of four power cycles": Unknown(_power_cycles),
    SLOW_SINE: Unknown(_slow_sine),
    "intermittent noise bursts (0.4 % of the record each)": Unknown(_noise_bursts, "noise"),
    "white-noise level growing with temperature": Unknown(_noise_with_temperature, "noise"),
    "line at 0.21·fs drifting +3 % over the record": Unknown(_chirp, "white"),
    "bias in log(1 + time since the temperature path changed / 60 s)": Unknown(_log_since_temperature_change),
    "asymmetric telegraph bias (mean dwells 1 % and 8 % of the record)": Unknown(_asymmetric_telegraph),
    "excess noise with a f^−1.5 spectrum": Unknown(_excess_f15),
    f"thermal_lag + {SHUPE_T}": Unknown(_shupe_in_temperature, with_effect="thermal_lag"),
    f"sf_asymmetry + {SF_SETTLING}": Unknown(_sf_settling, with_effect="sf_asymmetry"),
    f"bias_ramp + {SLOW_SINE}": Unknown(_slow_sine, with_effect="bias_ramp"),
}

#: continuous sweeps hold no rate: every sample is a rate change, so these shapes are the scale factor itself
NO_DWELLS = (SF_HYSTERESIS, SF_SETTLING, f"sf_asymmetry + {SF_SETTLING}")

PROFILES: dict[str, FreshProfile] = {
    # 13 minutes see 0.6 of the slow sine's period: bias_ramp leaves little of it (table of the doc)
    "S1": FreshProfile("S1 (13 min, 1000 Hz, 25 °C then two-point soaks −15 and 55 °C joined by 20 °C/min "
                       "ramps, ladder ±0.1…300 deg/s up in the cold soak and down in the hot one, 200 deg/s²)",
                       _s1, {"warmup_transient": {"tau_s": 60.0}, "table_angle_harmonic": {"phase_deg": -120.0},
                             "periodic_interference": {"freq_hz": 187.3}},
                       0.15, (5.0, 60.0), 0.1, catalogue_alike=(SLOW_SINE, f"bias_ramp + {SLOW_SINE}")),
    # heating only: h = +1 throughout, temp_hysteresis is the bias itself
    "S2": FreshProfile("S2 (100 min, 25 Hz, one linear ramp 0 → 50 °C at 0.556 °C/min between 5-minute soaks, "
                       "continuous sweeps 0 → ±250 → ∓250 → 0 deg/s at 2 deg/s² every 16.5 min, no dwells)",
                       _s2, {"warmup_transient": {"tau_s": 600.0}, "table_angle_harmonic": {"phase_deg": 75.0},
                             "periodic_interference": {"freq_hz": 7.9}},
                       3.0, (15.0, 400.0), 0.5, unobservable=("temp_hysteresis",), not_applicable=NO_DWELLS),
    "S3": FreshProfile("S3 (20 h, 2.5 Hz, cycle 25 → 65 → −25 → 25 °C with 1–2 h plateaus, ramps 1, 1.5 and "
                       "0.5 °C/min, ladder ±0.5…250 deg/s up and back down in each plateau only, 50 deg/s²)",
                       _s3, {"warmup_transient": {"tau_s": 3000.0}, "table_angle_harmonic": {"phase_deg": -30.0},
                             "periodic_interference": {"freq_hz": 0.83}},
                       1.0, (30.0, 2000.0), 1.5),
}

#: S1–S3 as a set: runs seeded 19000 + …, unknowns' shapes drawn from [seed, 2929]
SET = HeldOutSet("S", PROFILES, UNKNOWN, seed_base=19000, shape_stream=2929)
