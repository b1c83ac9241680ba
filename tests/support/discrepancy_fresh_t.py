"""A third held-out validation set for the discrepancy workflow (issue 29): profiles T1–T3, new unknowns.

The first two held-out sets (R1–R3, ``discrepancy_fresh``; S1–S3,
``discrepancy_fresh_s``) are being read while the workflow changes, so they stop
holding anything out. This set was made apart from that work, by the same rule
(``discrepancy_heldout``), without reading the workflow's internals or running
it on these cases, so that issue 29's targets can be measured on it once, at the
end. Whoever changes the workflow should not read this file.

* three procedures unlike P1–P3, Q1–Q3, R1–R3 and S1–S3 (``PROFILES``):
  T1, 25 min at 250 Hz, a fast temperature sine 30 ± 15 °C of period 12.5 min,
  the table running a geometric ladder with unequal positive and negative
  magnitudes (+0.4·2.5^k against −0.55·2.5^k deg/s, flipped in the last four
  cycles) all the time; T2, 5 h at
  8 Hz, an asymmetric staircase 20 → 70 → 45 → −30 → 0 °C (fast heating and
  cooling legs against slow ones), a few dwells and one unequal sweep per soak
  and a dwell pair in each ramp; T3, 9 h at 4 Hz, static-heavy: one long
  0.2 °C/min ramp 25 → 70 °C, a 2.5-hour hot soak and a 1 °C/min cool-back,
  a 10-minute rate block every 75 minutes, still otherwise;
* families of structure outside the catalogue that no earlier set had
  (``UNKNOWN``): a scale factor in dT/dt, a bias from the table's spin heating
  (ω² through a 300-s memory), a bias following a humidity-like triangle cycle,
  a bias at twice the table angle, the chamber air overshooting each setpoint
  it arrives at (unlogged), a noise level raised while the table slews, a
  readout that counts one sample's angle twice every 7.3 s, a scale factor
  modulated by the table angle, five single-sample outliers, a bias in the net
  table turns (cable wind-up), a compressor cycling while the chamber cools,
  a glass-transition step in the bias–temperature law, a line whose amplitude
  follows |ω|; and three combinations of a catalogue effect with one of them.

Sizes: 10σ by the rule of ``discrepancy_heldout`` (known-shape SNR of the
binned shape, norm against the white noise for lines and spikes, expected
likelihood ratio for a noise-level change). Runs are seeded 29000 + … (apart
from R's 9000 + … and S's 19000 + …).
"""

from __future__ import annotations

import math

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_heldout import FreshProfile, HeldOutSet, Unknown, scheduled_profile
from scipy.signal import lfilter

# --- the procedures ---------------------------------------------------------------------------

T1_FS_HZ, T1_DURATION_S = 250.0, 1500.0
T1_POSITIVE_DPS = tuple(0.4 * 2.5 ** k for k in range(8))       # 0.4 … 244 deg/s
T1_NEGATIVE_DPS = tuple(-0.55 * 2.5 ** k for k in range(8))     # −0.55 … −336 deg/s
T1_DWELL_S = 6.0
T1_CYCLE_STARTS_S = tuple(30.0 + 150.0 * k for k in range(9))
T1_MIRRORED_FROM = 5                     # cycles from this one on run the ladder with its signs flipped


def t1_temp_c(t_s: np.ndarray) -> np.ndarray:
    """30 ± 15 °C on a sine of period 750 s (peak slope 7.5 °C/min), starting at 30 °C heating."""
    return 30.0 + 15.0 * np.sin(2.0 * math.pi * t_s / 750.0)


def _t1() -> scenarios.Profile:
    """25 min at 250 Hz: the temperature sine; every 150 s a 16-dwell ladder (6 s each, 150 deg/s²).

    Each ladder alternates +0.4·2.5^k and −0.55·2.5^k deg/s upwards: the negative
    rates are larger, so ± dwells never mirror and the table winds up net turns
    for five cycles; the last four run the ladder with its signs flipped and
    unwind them.
    """
    ladder = tuple((r, T1_DWELL_S) for pair in zip(T1_POSITIVE_DPS, T1_NEGATIVE_DPS, strict=True) for r in pair)
    mirrored = tuple((-r, length) for r, length in ladder)
    first = scheduled_profile(T1_DURATION_S, T1_FS_HZ, t1_temp_c, ladder, T1_CYCLE_STARTS_S[:T1_MIRRORED_FROM],
                              150.0)
    last = scheduled_profile(T1_DURATION_S, T1_FS_HZ, t1_temp_c, mirrored, T1_CYCLE_STARTS_S[T1_MIRRORED_FROM:],
                             150.0)
    return scenarios.Profile(first.t_s, first.table_rate_dps + last.table_rate_dps, first.chamber_temp_c)


#: (setpoint °C, soak min, ramp °C/min to the next setpoint); the last soak lasts to the end
T2_STAIRS = ((20.0, 20.0, 4.0), (70.0, 35.0, 0.4), (45.0, 25.0, 3.0), (-30.0, 45.0, 0.5), (0.0, 15.0, 0.0))
T2_FS_HZ, T2_DURATION_S = 8.0, 18000.0
T2_SOAK_BLOCK = ((7.0, 60.0), (-23.0, 60.0), (61.0, 60.0), (0.0, 20.0))   # dwells, then the sweep
T2_SWEEP_DPS = (0.0, 180.0, -120.0, 0.0)                                  # at 1.5 deg/s²
T2_RAMP_BLOCK = ((15.0, 120.0), (-40.0, 120.0))


def t2_knots() -> tuple[np.ndarray, np.ndarray]:
    """Knots (s, °C) of ``T2_STAIRS``: soak, ramp, soak, …"""
    times, temps, at = [], [], 0.0
    for i, (setpoint, soak_min, ramp) in enumerate(T2_STAIRS):
        times += [at, at + 60.0 * soak_min]
        temps += [setpoint, setpoint]
        at += 60.0 * soak_min
        if i + 1 < len(T2_STAIRS):
            at += abs(T2_STAIRS[i + 1][0] - setpoint) / ramp * 60.0
    return np.array(times), np.array(temps)


def _sweep(t: np.ndarray, start_s: float) -> np.ndarray:
    """0 → +180 → −120 → 0 deg/s at 1.5 deg/s² from ``start_s`` (zero outside)."""
    legs_s = np.abs(np.diff(T2_SWEEP_DPS)) / 1.5
    knots_s = start_s + np.concatenate([[0.0], np.cumsum(legs_s)])
    inside = (t >= knots_s[0]) & (t <= knots_s[-1])
    return np.where(inside, np.interp(t, knots_s, T2_SWEEP_DPS), 0.0)


def _t2() -> scenarios.Profile:
    """5 h at 8 Hz on ``t2_knots``: 3 min into each soak three dwells then one unequal sweep; a dwell pair
    (+15, −40 deg/s) in the middle of each ramp; 20 deg/s² slews, still elsewhere."""
    times, temps = t2_knots()
    temp = lambda t: np.interp(t, times, temps)  # noqa: E731
    soak_starts = times[0::2]
    ramp_middles = 0.5 * (times[1:-1:2] + times[2::2])
    dwells = scheduled_profile(T2_DURATION_S, T2_FS_HZ, temp, T2_SOAK_BLOCK, tuple(soak_starts + 180.0), 20.0)
    ramps = scheduled_profile(T2_DURATION_S, T2_FS_HZ, temp, T2_RAMP_BLOCK, tuple(ramp_middles - 120.0), 20.0)
    block_s = sum(length for _, length in T2_SOAK_BLOCK) + 10.0
    sweeps = sum(_sweep(dwells.t_s, s + 180.0 + block_s) for s in soak_starts)
    return scenarios.Profile(dwells.t_s, dwells.table_rate_dps + ramps.table_rate_dps + sweeps,
                             dwells.chamber_temp_c)


T3_KNOTS_MIN = ((0.0, 25.0), (80.0, 25.0), (305.0, 70.0), (455.0, 70.0), (500.0, 25.0), (540.0, 25.0))
T3_FS_HZ, T3_DURATION_S = 4.0, 32400.0
T3_BLOCK = ((2.0, 60.0), (-3.0, 60.0), (30.0, 40.0), (-45.0, 40.0), (120.0, 30.0), (-160.0, 30.0), (1.0, 370.0))
T3_BLOCK_STARTS_S = tuple(60.0 * (20.0 + 75.0 * k) for k in range(7))


def _t3() -> scenarios.Profile:
    """9 h at 4 Hz: 80 min at 25 °C, 0.2 °C/min to 70 °C, 150 min there, 1 °C/min back, 40 min at 25 °C.

    Static-heavy: every 75 minutes a 10.5-minute block (± dwells of unequal size
    and a slow full turn at 1 deg/s, 30 deg/s²), still otherwise (about 87 %
    of the record).
    """
    knots = np.array(T3_KNOTS_MIN)
    return scheduled_profile(T3_DURATION_S, T3_FS_HZ, lambda t: np.interp(t, 60.0 * knots[:, 0], knots[:, 1]),
                             T3_BLOCK, T3_BLOCK_STARTS_S, 30.0)


# --- structure outside the catalogue -------------------------------------------------------------

def _slope_c_per_min(p: scenarios.Profile) -> np.ndarray:
    return np.gradient(p.chamber_temp_c, p.t_s) * 60.0


def _angle_deg(p: scenarios.Profile) -> np.ndarray:
    """Table angle θ = ∫ω dt (deg), 0 at the start."""
    return np.cumsum(p.table_rate_dps) / p.fs_hz


def _low_pass(x: np.ndarray, tau_s: float, fs_hz: float) -> np.ndarray:
    """First-order memory of ``x`` with time constant ``tau_s``, starting from x[0]."""
    a = 1.0 / (tau_s * fs_hz)
    out, _ = lfilter([a], [1.0, a - 1.0], x, zi=[x[0] * (1.0 - a)])
    return out


def _sf_in_temp_rate(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·dT/dt: a scale factor moved by a thermal gradient across the sensing element while T changes."""
    return p.table_rate_dps * _slope_c_per_min(p)


def _spin_heating(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω² through a 300-s first-order memory: the table's bearing and motor heat the mount while it spins."""
    return _low_pass(p.table_rate_dps ** 2, 300.0, p.fs_hz)


def _humidity_cycle(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A triangle between 0 and 1 with legs of 8–20 min drawn at random: the chamber's humidity controller
    letting moisture rise, then drying it (the log has no humidity column)."""
    legs_s = rng.uniform(480.0, 1200.0, size=int(p.t_s[-1] / 480.0) + 2)
    knots_s = np.concatenate([[0.0], np.cumsum(legs_s)]) - rng.uniform(0.0, legs_s[0])
    levels = (np.arange(knots_s.size) + rng.integers(2)) % 2
    return np.interp(p.t_s, knots_s, levels.astype(float))


def _angle_second_harmonic(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """cos(2θ − 30°): a bias twice per table turn (an elliptical mount or a magnetic quadrupole)."""
    return np.cos(np.radians(2.0 * _angle_deg(p) - 30.0))


def _setpoint_arrivals(p: scenarios.Profile) -> tuple[np.ndarray, np.ndarray]:
    """Seconds since the chamber last arrived at a setpoint (a soak of ≥ 1 min; inf before any) and the sign
    of the ramp that reached it."""
    slope = _slope_c_per_min(p)
    moving = np.abs(slope) > 1e-6
    held = max(1, int(round(60.0 * p.fs_hz)))       # a soak: the path stays still for a minute at least
    still_for = np.convolve(~moving, np.ones(held), mode="full")[held - 1:] >= held
    arrived = np.flatnonzero(moving[:-1] & still_for[1:]) + 1
    since, sign = np.full(p.t_s.size, np.inf), np.zeros(p.t_s.size)
    for i in arrived:
        since[i:] = p.t_s[i:] - p.t_s[i]
        sign[i:] = np.sign(slope[i - 1])
    return since, sign


def _chamber_overshoot(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """The air overshooting each setpoint it arrives at (a damped 10-min swing, 5-min decay, in the ramp's
    direction), felt through the bias tempco but not in the logged setpoint path."""
    since, sign = _setpoint_arrivals(p)
    with np.errstate(invalid="ignore"):
        swing = sign * np.exp(-since / 300.0) * np.sin(2.0 * math.pi * since / 600.0)
    return np.nan_to_num(swing, nan=0.0)


def _slew_noise(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Relative variance 1 while the table accelerates (motor vibration under torque), 0 elsewhere."""
    return (np.abs(np.diff(p.table_rate_dps, prepend=p.table_rate_dps[0])) > 0.0).astype(float)


def _double_count(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Every 7.3 s one sample carries its neighbour's angle too (a readout FIFO read twice): +ω there."""
    period = max(1, int(round(7.3 * p.fs_hz)))
    at = np.zeros(p.t_s.size)
    at[int(rng.integers(period))::period] = 1.0
    return at * p.table_rate_dps


def _sf_by_angle(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·cos(θ − 70°): a scale factor modulated once per turn (a slip ring or an axis wobble)."""
    return p.table_rate_dps * np.cos(np.radians(_angle_deg(p) - 70.0))


def _outliers(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Five single samples at random times with Laplace-distributed values (serial framing glitches)."""
    out = np.zeros(p.t_s.size)
    out[rng.choice(p.t_s.size, size=5, replace=False)] = rng.laplace(size=5)
    return out


def _cable_windup(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Net table turns: the cable's torque on the mount grows as the table winds up."""
    return _angle_deg(p) / 360.0


COMPRESSOR_PERIOD_S, COMPRESSOR_DUTY = 1020.0, 0.35


def _compressor(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A 17-minute on/off cycle (35 % on) while the chamber is below 22 °C or cooling: the refrigeration
    compressor's vibration and field."""
    cooling = (p.chamber_temp_c < 22.0) | (_slope_c_per_min(p) < -0.05)
    phase = (p.t_s / COMPRESSOR_PERIOD_S + rng.uniform()) % 1.0
    return (cooling & (phase < COMPRESSOR_DUTY)).astype(float)


def _glass_transition(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """tanh((T − Tg)/3 °C), Tg at 60 % of the record's temperature span: an adhesive softening."""
    temp = p.chamber_temp_c
    glass_c = temp.min() + 0.6 * (temp.max() - temp.min())
    return np.tanh((temp - glass_c) / 3.0)


def _line_by_rate(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A line at 0.37·fs (at most 47.3 Hz) whose amplitude follows |ω|: the table drive's PWM pickup."""
    freq_hz = min(0.37 * p.fs_hz, 47.3)
    return np.abs(p.table_rate_dps) * np.sin(2.0 * math.pi * freq_hz * p.t_s)


SF_DTDT = "scale factor ∝ dT/dt (ω·dT/dt)"
ANGLE_2H = "bias at twice the table angle (cos(2θ − 30°))"
GLASS = "bias–temperature step at a glass transition (tanh((T − Tg)/3 °C))"
OVERSHOOT = "unlogged chamber-air overshoot at each setpoint arrival (10-min swing, 5-min decay)"
COMPRESSOR = "bias on a 17-min compressor cycle while below 22 °C or cooling"

UNKNOWN: dict[str, Unknown] = {
    SF_DTDT: Unknown(_sf_in_temp_rate),
    "bias from table spin heating (ω² through a 300-s memory)": Unknown(_spin_heating),
    "bias on a humidity-like triangle cycle (legs 8–20 min)": Unknown(_humidity_cycle),
    ANGLE_2H: Unknown(_angle_second_harmonic),
    OVERSHOOT: Unknown(_chamber_overshoot),
    "white-noise level raised while the table slews": Unknown(_slew_noise, "noise"),
    "one sample's angle counted twice every 7.3 s (spikes ∝ ω)": Unknown(_double_count, "white"),
    "scale factor modulated by the table angle (ω·cos(θ − 70°))": Unknown(_sf_by_angle),
    "five single-sample outliers (Laplace values)": Unknown(_outliers, "white"),
    "bias ∝ net table turns (cable wind-up)": Unknown(_cable_windup),
    COMPRESSOR: Unknown(_compressor),
    GLASS: Unknown(_glass_transition),
    "line at 0.37·fs with amplitude ∝ |ω|": Unknown(_line_by_rate, "white"),
    f"table_angle_harmonic + {ANGLE_2H}": Unknown(_angle_second_harmonic, with_effect="table_angle_harmonic"),
    f"bias_temp_quadratic + {GLASS}": Unknown(_glass_transition, with_effect="bias_temp_quadratic"),
    f"temp_rate_bias + {SF_DTDT}": Unknown(_sf_in_temp_rate, with_effect="temp_rate_bias"),
}

#: ω·dT/dt is what thermal_lag does to the scale-factor tempco (ω·k·τ·dT/dt) wherever the table turns at a
#: steady dT/dt: on T1 (a sine, rates everywhere) 2.8σ of 10 is left beside thermal_lag, on T3 (rates in
#: a constant-slope ramp) 0.2σ; on T2 (four ramps of different slopes) 5.0σ
SF_DTDT_ALIKE = (SF_DTDT, f"temp_rate_bias + {SF_DTDT}")

PROFILES: dict[str, FreshProfile] = {
    # a sine never arrives at a setpoint: no overshoot to feel
    "T1": FreshProfile("T1 (25 min, 250 Hz, temperature sine 30 ± 15 °C of period 12.5 min, geometric ladder "
                       "+0.4·2.5^k / −0.55·2.5^k deg/s (k 0…7, 6-s dwells, 150 deg/s²) every 150 s throughout, signs "
                       "flipped in the last four cycles)",
                       _t1, {"warmup_transient": {"tau_s": 90.0}, "table_angle_harmonic": {"phase_deg": -160.0},
                             "periodic_interference": {"freq_hz": 41.3}},
                       0.6, (8.0, 90.0), 0.2, catalogue_alike=SF_DTDT_ALIKE, not_applicable=(OVERSHOOT,)),
    "T2": FreshProfile("T2 (5 h, 8 Hz, asymmetric staircase 20 → 70 → 45 → −30 → 0 °C, ramps 4, 0.4, 3 and "
                       "0.5 °C/min, soaks 15–45 min; per soak dwells +7, −23, +61 deg/s and a sweep "
                       "0 → +180 → −120 → 0 at 1.5 deg/s², a +15/−40 deg/s pair mid-ramp, 20 deg/s²)",
                       _t2, {"warmup_transient": {"tau_s": 900.0}, "table_angle_harmonic": {"phase_deg": 100.0},
                             "periodic_interference": {"freq_hz": 1.93}},
                       8.0, (40.0, 1200.0), 1.2),
    "T3": FreshProfile("T3 (9 h, 4 Hz, static-heavy: 25 °C, one 0.2 °C/min ramp to 70 °C, 2.5-h hot soak, "
                       "1 °C/min back to 25 °C; every 75 min a 10.5-min block of ±2…160 deg/s dwells of "
                       "unequal size and a 1 deg/s turn, 30 deg/s²)",
                       _t3, {"warmup_transient": {"tau_s": 4000.0}, "table_angle_harmonic": {"phase_deg": 55.0},
                             "periodic_interference": {"freq_hz": 0.57}},
                       2.5, (250.0, 3500.0), 2.5, catalogue_alike=SF_DTDT_ALIKE),
}

#: T1–T3 as a set: runs seeded 29000 + …, unknowns' shapes drawn from [seed, 4747]
SET = HeldOutSet("T", PROFILES, UNKNOWN, seed_base=29000, shape_stream=4747)
