"""A fourth held-out validation set for the discrepancy workflow (issue 29): profiles U1–U3, new unknowns.

R1–R3, S1–S3 and T1–T3 (``discrepancy_fresh``, ``_s``, ``_t``) have been run
and read while the workflow changed, so they stop holding anything out. This
set was made apart from that work, by the same rule (``discrepancy_heldout``),
without reading the workflow's internals or running it on these cases, so that
issue 29's targets can be measured on it once, at the end. Whoever changes the
workflow should not read this file.

* three procedures unlike P1–P3, Q1–Q3, R1–R3, S1–S3 and T1–T3 (``PROFILES``):
  U1, 12 min at 500 Hz, a thermal-shock chamber (20 → 65 → 0 °C setpoint steps
  the air follows with a critically damped 90-s response, up to 11 °C/min
  heating and 15 °C/min cooling), the table running the same ±0.25…240 deg/s
  rungs in a different shuffled order every 65 s; U2, 3.5 h at 12 Hz, plateaus
  25 → 50 → 15 → 40 → −10 → 20 °C joined by raised-cosine (S-shaped)
  transitions, a stepped rate sweep 0 → +150 → −150 → 0 deg/s in 30 deg/s
  steps in each plateau and a slow 2.5 deg/s turn through each transition;
  U3, 15 h at 1.25 Hz, static-heavy in a room-like diurnal temperature
  (21 − 4·cos φ − 1.5·sin 2φ °C, a 12-h "day"), a 7-minute rate block every
  100 minutes, still otherwise;
* families of structure outside the catalogue that no earlier set had
  (``UNKNOWN``): a second, unlogged table axis indexing (Earth-rate levels and
  cross-coupled pulses), a bias through a backlash (play) in temperature,
  vibration rectification in |ω|³, a line at 24× the table's turn rate (motor
  cogging), a table tilt growing with temperature (ΔT·cos(θ − 20°)), a bias in
  d²T/dt², a loose slip-ring contact above a rate, a random walk that advances
  only while the table turns, a Gauss–Markov bias whose σ grows with
  temperature, a narrow-band random bias (the chamber controller hunting), an
  odd quadratic scale factor ω·|ω|, the heater's field (a hinge in heater
  power), a bias in one 15° sector of the table angle; and three combinations
  of a catalogue effect with one of them.

Sizes: 10σ by the rule of ``discrepancy_heldout`` (known-shape SNR of the
binned shape; norm against the white noise for the cogging line). Runs are
seeded 39000 + … (apart from R's 9000, S's 19000 and T's 29000 + …).
"""

from __future__ import annotations

import math

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_heldout import FreshProfile, HeldOutSet, Unknown, scheduled_profile
from scipy.signal import lfilter

# --- the procedures ---------------------------------------------------------------------------

U1_FS_HZ, U1_DURATION_S = 500.0, 720.0
#: (time s, setpoint °C): the setpoint steps; the air follows each with a critically damped response
U1_SETPOINTS = ((0.0, 20.0), (45.0, 65.0), (390.0, 0.0))
U1_AIR_TAU_S = 90.0
U1_RUNGS_DPS = (0.25, 1.0, 4.0, 15.0, 60.0, 240.0)
U1_DWELL_S, U1_ACCEL_DPS2 = 4.0, 300.0
U1_CYCLE_STARTS_S = tuple(10.0 + 65.0 * k for k in range(11))
U1_SHUFFLE_SEED = 20261124


def u1_temp_c(t_s: np.ndarray) -> np.ndarray:
    """Air after each setpoint step: T_sp + (A + B·s)·e^(−s), s = time since the step / τ.

    A critically damped approach (heater and air mass): A and B carry over the
    air's temperature and slope at the step, so the path has no corner; from
    rest the peak slope is ΔT/(e·τ).
    """
    temp = np.full(t_s.size, U1_SETPOINTS[0][1])
    previous = (0.0, U1_SETPOINTS[0][1], 0.0, 0.0)             # (start s, setpoint °C, A, B)
    for start_s, setpoint_c in U1_SETPOINTS[1:]:
        p_start, p_setpoint, a, b = previous
        s = (start_s - p_start) / U1_AIR_TAU_S
        level_c = p_setpoint + (a + b * s) * math.exp(-s)
        slope_c_per_s = (b - a - b * s) * math.exp(-s) / U1_AIR_TAU_S
        a = level_c - setpoint_c
        previous = (start_s, setpoint_c, a, a + U1_AIR_TAU_S * slope_c_per_s)
        after = t_s >= start_s
        s = (t_s[after] - start_s) / U1_AIR_TAU_S
        temp[after] = setpoint_c + (previous[2] + previous[3] * s) * np.exp(-s)
    return temp


def u1_cycles() -> tuple[tuple[tuple[float, float], ...], ...]:
    """Every cycle's dwells: the twelve ± rungs, 4 s each, in a fresh shuffled order (fixed seed)."""
    rungs = np.array([sign * r for r in U1_RUNGS_DPS for sign in (1.0, -1.0)])
    rng = np.random.default_rng(U1_SHUFFLE_SEED)
    return tuple(tuple((float(r), U1_DWELL_S) for r in rng.permutation(rungs)) for _ in U1_CYCLE_STARTS_S)


def _u1() -> scenarios.Profile:
    """12 min at 500 Hz on ``u1_temp_c``; every 65 s the twelve rungs in a new order (300 deg/s²).

    A shuffled order is what a lab uses against drift aliasing into the ladder:
    no rate always follows the same one, so a rate's history changes every cycle.
    """
    parts = [scheduled_profile(U1_DURATION_S, U1_FS_HZ, u1_temp_c, cycle, (start,), U1_ACCEL_DPS2)
             for cycle, start in zip(u1_cycles(), U1_CYCLE_STARTS_S, strict=True)]
    return scenarios.Profile(parts[0].t_s, sum(p.table_rate_dps for p in parts), parts[0].chamber_temp_c)


U2_FS_HZ, U2_DURATION_S = 12.0, 12600.0
U2_PLATEAUS_C = (25.0, 50.0, 15.0, 40.0, -10.0, 20.0)
U2_MEAN_RAMPS_C_PER_MIN = (2.0, 1.2, 2.5, 1.5, 3.0)
U2_PLATEAU_MIN = 18.0
U2_SWEEP_DPS = tuple(30.0 * k for k in range(-5, 6))        # −150 … +150 deg/s
U2_SWEEP_DWELL_S, U2_TURN_DPS, U2_ACCEL_DPS2 = 12.0, 2.5, 6.0


def u2_segments() -> list[tuple[float, float, float, float]]:
    """(start s, end s, from °C, to °C) of every transition; plateaus lie between them."""
    segments, at = [], 60.0 * U2_PLATEAU_MIN
    for a, b, ramp in zip(U2_PLATEAUS_C[:-1], U2_PLATEAUS_C[1:], U2_MEAN_RAMPS_C_PER_MIN, strict=True):
        length_s = abs(b - a) / ramp * 60.0
        segments.append((at, at + length_s, a, b))
        at += length_s + 60.0 * U2_PLATEAU_MIN
    return segments


def u2_temp_c(t_s: np.ndarray) -> np.ndarray:
    """Plateaus joined by raised-cosine transitions: the chamber eases into and out of every change, so
    dT/dt rises and falls smoothly (peak π/2 × the mean ramp) instead of jumping as on a linear ramp."""
    temp = np.full(t_s.size, U2_PLATEAUS_C[0])
    for start, end, a, b in u2_segments():
        inside = (t_s >= start) & (t_s < end)
        temp[inside] = a + (b - a) * 0.5 * (1.0 - np.cos(math.pi * (t_s[inside] - start) / (end - start)))
        temp[t_s >= end] = b
    return temp


def _u2() -> scenarios.Profile:
    """3.5 h at 12 Hz on ``u2_temp_c``: 3 min into each plateau a stepped sweep 0 → +150 → −150 → 0 deg/s
    (30 deg/s steps held 12 s, 5 of them slewing), a 2.5 deg/s turn through each transition; 6 deg/s²."""
    t = np.arange(int(round(U2_DURATION_S * U2_FS_HZ))) / U2_FS_HZ
    steps = U2_SWEEP_DPS[5:] + U2_SWEEP_DPS[-2::-1] + U2_SWEEP_DPS[1:6]     # 0 → +150 → −150 → 0
    rate = np.zeros_like(t)
    plateau_starts = [0.0] + [end for _, end, _, _ in u2_segments()]
    for start in plateau_starts:
        at = start + 180.0
        for level in steps:
            rate[(t >= at) & (t < at + U2_SWEEP_DWELL_S)] = level
            at += U2_SWEEP_DWELL_S
    for start, end, _, _ in u2_segments():
        rate[(t >= start) & (t < end)] = U2_TURN_DPS
    return scenarios.Profile(t, scenarios._slewed(rate, U2_FS_HZ, U2_ACCEL_DPS2), u2_temp_c(t))


U3_FS_HZ, U3_DURATION_S = 1.25, 54000.0
U3_DAY_S = 43200.0
U3_BLOCK = ((0.7, 45.0), (-0.7, 45.0), (9.0, 40.0), (-9.0, 40.0), (65.0, 30.0), (-65.0, 30.0), (2.0, 180.0))
U3_BLOCK_STARTS_S = tuple(60.0 * (40.0 + 100.0 * k) for k in range(9))


def u3_temp_c(t_s: np.ndarray) -> np.ndarray:
    """A room's day, compressed to 12 h: 21 − 4·cos φ − 1.5·sin 2φ °C, 16.2 … 25.8 °C (a quick morning
    warm-up, up to 0.061 °C/min, a slower evening cool-down, 0.032 °C/min at most; never held)."""
    phi = 2.0 * math.pi * t_s / U3_DAY_S
    return 21.0 - 4.0 * np.cos(phi) - 1.5 * np.sin(2.0 * phi)


def _u3() -> scenarios.Profile:
    """15 h at 1.25 Hz on ``u3_temp_c``: every 100 min a 7-minute block (±0.7, ±9, ±65 deg/s dwells and
    a full turn at 2 deg/s, 10 deg/s²), still otherwise (about 93 % of the record)."""
    return scheduled_profile(U3_DURATION_S, U3_FS_HZ, u3_temp_c, U3_BLOCK, U3_BLOCK_STARTS_S, 10.0)


# --- structure outside the catalogue -------------------------------------------------------------

def _angle_deg(p: scenarios.Profile) -> np.ndarray:
    """Table angle θ = ∫ω dt (deg), 0 at the start."""
    return np.cumsum(p.table_rate_dps) / p.fs_hz


def _span_unit(x: np.ndarray) -> np.ndarray:
    """``x`` moved and scaled to [0, 1] over the record."""
    return (x - x.min()) / (x.max() - x.min())


GIMBAL_MOVES, GIMBAL_MOVE_S, GIMBAL_PULSE = 5, 9.0, 3.0


def _gimbal_indexing(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A second table axis (not in the log) indexed 90° five times at random moments: the input axis then
    sees Earth's rate at cos(k·90° + 35°), and a 9-s cross-coupled pulse while the outer axis turns."""
    times = np.sort(rng.uniform(0.1, 0.9, size=GIMBAL_MOVES)) * p.t_s[-1]
    position = np.searchsorted(times, p.t_s, side="right")
    level = np.cos(np.radians(90.0 * position + 35.0))
    moving = np.zeros(p.t_s.size)
    for start in times:
        moving[(p.t_s >= start) & (p.t_s < start + GIMBAL_MOVE_S)] = GIMBAL_PULSE
    return level + moving


def _temperature_play(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Temperature through a backlash of width 25 % of the span (a mount that slips only once its stress
    exceeds friction): the bias follows T on a branch and holds still for a while after every reversal."""
    temp = p.chamber_temp_c
    half = 0.125 * (temp.max() - temp.min())
    out = np.empty(temp.size)
    y = temp[0]
    for i, x in enumerate(temp.tolist()):
        y = min(max(y, x - half), x + half)
        out[i] = y
    return out


RESONANCE_DPS, RESONANCE_HALF_WIDTH_DPS = 60.0, 15.0


def _resonance(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A Lorentzian in |ω| at 60 deg/s (half width 15): there the motor's 24-per-turn cogging (4 Hz) meets
    the fixture's resonance, and the gyro rectifies the vibration into a bias."""
    x = (np.abs(p.table_rate_dps) - RESONANCE_DPS) / RESONANCE_HALF_WIDTH_DPS
    return 1.0 / (1.0 + x * x)


COGGING_POLES = 24


def _cogging(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """cos(24·θ): the drive motor's cogging shakes the table 24 times per turn, a line at 24·ω/360 Hz that
    follows the table rate (a fixed bias at each angle the table stops at)."""
    return np.cos(np.radians(COGGING_POLES * _angle_deg(p)))


def _tilt_with_temperature(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """(T − mid-span)·cos(θ − 20°): the fixture expands unevenly, tilting the table top, so the input axis
    picks up Earth's horizontal rate in proportion to the temperature."""
    temp = p.chamber_temp_c
    middle = 0.5 * (temp.max() + temp.min())
    return (temp - middle) / (temp.max() - temp.min()) * np.cos(np.radians(_angle_deg(p) - 20.0))


def _temp_curvature(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """d²T/dt² (°C/min²): a gradient across the coil set by how fast the heat flux into it changes (the
    next term after the Shupe dT/dt of a two-layer thermal network)."""
    slope = np.gradient(p.chamber_temp_c, p.t_s) * 60.0
    return np.gradient(slope, p.t_s) * 60.0


TURNING_DPS = 0.1


def _turning_offset(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """1 whenever the table turns (|ω| > 0.1 deg/s), at any speed: the slip-ring brushes' contact noise,
    rectified into a fixed offset on the gyro's supply while they slide."""
    return (np.abs(p.table_rate_dps) > TURNING_DPS).astype(float)


def _turning_random_walk(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A random walk that steps only while the table turns (steps ∝ √(angle turned)): slip-ring contact
    resistance wearing as it rotates, still when the table is."""
    turned = np.abs(p.table_rate_dps) / p.fs_hz
    return np.cumsum(np.sqrt(turned) * rng.standard_normal(p.t_s.size))


def _hot_markov(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A Gauss–Markov bias (τ 1/40 of the record) whose σ grows e²-fold from the coldest to the hottest
    point: a source's intensity noise that rises with temperature (not stationary)."""
    tau_s = p.t_s[-1] / 40.0
    a = math.exp(-1.0 / (tau_s * p.fs_hz))
    sigma = np.exp(2.0 * _span_unit(p.chamber_temp_c))
    drive = math.sqrt(1.0 - a * a) * sigma * rng.standard_normal(p.t_s.size)
    out, _ = lfilter([1.0], [1.0, -a], drive, zi=[a * sigma[0] * rng.standard_normal()])
    return out


HUNT_PERIOD_S, HUNT_DAMPING = 240.0, 1.0 / 16.0


def _hunting(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """A narrow-band random bias near a 4-min period (a second-order resonance, ζ 1/16): the chamber's
    controller hunting around the setpoint with a wandering amplitude and phase, felt through the tempco."""
    w0 = 2.0 * math.pi / HUNT_PERIOD_S / p.fs_hz
    r = math.exp(-HUNT_DAMPING * w0)
    burn = int(10.0 / (HUNT_DAMPING * w0))                   # ten decay times: start in steady state
    x = lfilter([1.0], [1.0, -2.0 * r * math.cos(w0), r * r], rng.standard_normal(p.t_s.size + burn))
    return x[burn:]


SF_CYCLE_S = 2220.0


def _sf_cycle(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·sin(2π·t/37 min): the source's current supply sits in the lab air, which the building's HVAC
    cycles; the scale factor follows it (the chamber does not shield the electronics outside it)."""
    return p.table_rate_dps * np.sin(2.0 * math.pi * p.t_s / SF_CYCLE_S)


HEATER_AMBIENT_C, HEATER_LEAD_S = 22.0, 240.0


def _heater_field(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """max(0, (T − 22 °C) + 240 s·dT/dt): the heater's DC current (holding above the room plus driving a
    rise; off below) and its field through the fibre's Faraday sensitivity."""
    slope_c_per_s = np.gradient(p.chamber_temp_c, p.t_s)
    return np.maximum(0.0, p.chamber_temp_c - HEATER_AMBIENT_C + HEATER_LEAD_S * slope_c_per_s)


SECTOR_DEG = (200.0, 215.0)


def _angle_sector(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """1 while the table angle is in 200–215°: a slip-ring brush crossing a gap in its track."""
    angle = np.mod(_angle_deg(p), 360.0)
    return ((angle >= SECTOR_DEG[0]) & (angle < SECTOR_DEG[1])).astype(float)


GIMBAL = "second table axis indexed 90° five times (unlogged): Earth-rate levels and 9-s cross-coupled pulses"
PLAY = "bias through a temperature backlash (play of 25 % of the span)"
RESONANCE = "vibration rectified at a table resonance (Lorentzian in |ω| at 60 deg/s)"
TILT = "table tilt growing with temperature (ΔT·cos(θ − 20°))"
CURVATURE = "bias ∝ d²T/dt²"
TURNING = "offset whenever the table turns (slip-ring brushes sliding)"
HEATER = "heater field: max(0, (T − 22 °C) + 240 s·dT/dt)"

UNKNOWN: dict[str, Unknown] = {
    GIMBAL: Unknown(_gimbal_indexing),
    PLAY: Unknown(_temperature_play),
    RESONANCE: Unknown(_resonance),
    "line at 24× the table's turn rate (motor cogging, cos 24θ)": Unknown(_cogging, "white"),
    TILT: Unknown(_tilt_with_temperature),
    CURVATURE: Unknown(_temp_curvature),
    TURNING: Unknown(_turning_offset),
    "random walk advancing only while the table turns": Unknown(_turning_random_walk),
    "Gauss–Markov bias whose σ grows with temperature (τ 1/40 of the record)": Unknown(_hot_markov),
    "narrow-band random bias near a 4-min period (controller hunting)": Unknown(_hunting),
    "scale factor on a 37-min HVAC cycle (ω·sin(2πt/37 min))": Unknown(_sf_cycle),
    HEATER: Unknown(_heater_field),
    "bias in one 15° sector of the table angle (slip-ring brush gap)": Unknown(_angle_sector),
    f"thermal_lag + {CURVATURE}": Unknown(_temp_curvature, with_effect="thermal_lag"),
    f"sf_asymmetry + {TURNING}": Unknown(_turning_offset, with_effect="sf_asymmetry"),
    f"warmup_transient + {GIMBAL}": Unknown(_gimbal_indexing, with_effect="warmup_transient"),
}

PROFILES: dict[str, FreshProfile] = {
    # thermal_lag is sized at the sizing's floor τ 1 s here, a 29σ signature (10σ would need τ ≈ 0.3 s)
    # two monotone legs: the backlash is the path shifted against its motion, a tempco and a dT/dt bias
    # there (2.8σ of 10 left beside temp_rate_bias; 7.7σ on U2, 6.7σ on U3, where the path turns back)
    "U1": FreshProfile("U1 (12 min, 500 Hz, thermal shock: setpoint steps 20 → 65 → 0 °C followed by the air "
                       "with a critically damped 90-s response, up to 11 °C/min up and 15 °C/min down; ±0.25, 1, "
                       "4, 15, 60, 240 deg/s rungs of 4 s in a new shuffled order every 65 s, 300 deg/s²)",
                       _u1, {"warmup_transient": {"tau_s": 100.0}, "table_angle_harmonic": {"phase_deg": -45.0},
                             "periodic_interference": {"freq_hz": 37.44}},
                       0.5, (12.0, 70.0), 0.3, catalogue_alike=(PLAY,)),
    "U2": FreshProfile("U2 (3.5 h, 12 Hz, plateaus 25 → 50 → 15 → 40 → −10 → 20 °C of 18 min joined by "
                       "raised-cosine transitions (mean 1.2–3 °C/min); per plateau a stepped sweep "
                       "0 → +150 → −150 → 0 deg/s in 30 deg/s steps of 12 s, a 2.5 deg/s turn through every "
                       "transition, 6 deg/s²)",
                       _u2, {"warmup_transient": {"tau_s": 600.0}, "table_angle_harmonic": {"phase_deg": 130.0},
                             "periodic_interference": {"freq_hz": 4.16}},
                       4.0, (25.0, 700.0), 0.8),
    # three dwell magnitudes (0.7, 9, 65 deg/s): the bump at 60 deg/s is an even rate law there (0.1σ of 10
    # left beside sf_nonlinearity_quadratic; 9.8σ on U1 and 9.5σ on U2, whose rates reach past it)
    "U3": FreshProfile("U3 (15 h, 1.25 Hz, static-heavy in a room-like 12-h day 21 − 4·cos φ − 1.5·sin 2φ °C; "
                       "every 100 min a 7-min block of ±0.7, ±9, ±65 deg/s dwells and a 2 deg/s full turn, "
                       "10 deg/s², still otherwise)",
                       _u3, {"warmup_transient": {"tau_s": 3000.0}, "table_angle_harmonic": {"phase_deg": -110.0},
                             "periodic_interference": {"freq_hz": 0.213}},
                       1.2, (150.0, 2400.0), 4.0, catalogue_alike=(RESONANCE,)),
}

#: U1–U3 as a set: runs seeded 39000 + …, unknowns' shapes drawn from [seed, 5959]
SET = HeldOutSet("U", PROFILES, UNKNOWN, seed_base=39000, shape_stream=5959)
