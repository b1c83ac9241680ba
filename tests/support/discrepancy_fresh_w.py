"""A sixth held-out validation set for the discrepancy workflow (issue 29): profiles W1–W3, new unknowns.

V1–V3 (``discrepancy_fresh_v``) have been read by the people changing the
workflow, so they no longer hold anything out. This set was made apart from
that work, by the same rule (``discrepancy_heldout``), without reading the
workflow's internals or running it on these cases. Whoever changes the
workflow should not read this file.

* three procedures unlike P1–P3, Q1–Q3, R1–R3, S1–S3, T1–T3, U1–U3 and V1–V3
  (``PROFILES``): W1, 22 min at 120 Hz, a chamber held at 35 °C whose door is
  opened twice for 45 s (the air falls towards the 22 °C room with τ 50 s and
  recovers with τ 120 s), every 2 min a coarse ladder ±10, ±30, ±100, ±300
  deg/s of 6-s dwells at a high table acceleration (500 deg/s²); W2, 4.75 h at
  3 Hz, the widest path of any set: a 30-min soak at −40 °C, one slow
  0.6 °C/min ramp to 70 °C, a 30-min hot soak, a fast 3 °C/min cool to 25 °C
  and a final hold, a rate block (±0.5, ±5, ±50, ±200 deg/s dwells of 30 s and
  a 2 deg/s full turn) every 45 min and in the final hold, static otherwise;
  W3, 75 min at 24 Hz, a temperature sine of period 25 min and ±12 °C around a
  mean drifting 18 → 30 °C, every 5 min ±3, ±45, ±180 deg/s dwells of 8 s and a
  7.5 deg/s full turn (150 deg/s²);
* families outside the catalogue that no earlier set had (``UNKNOWN``): a bias
  doubling every 10 °C (a dark current), a bias in |dT/dt| (the chamber's
  blower), a scale-factor dip in a band of rates (a fixture resonance), a bias
  relaxing after cooling only, a bias in the total angle turned (brush wear),
  scale-factor hops, a white-noise variance growing through the record, the
  table's servo lagging and ringing through every rate change, a scale factor
  ageing in time, a sensor lagging the air faster when heating than when
  cooling, a ripple line whose amplitude follows temperature, a square wave in
  the table angle (cable tilt); and three combinations of a catalogue effect
  with one of them.

Noise: as in V, a run's seed depends on its profile (``profile_seed_stride``
1000: profile i's runs are seeded 59000 + 1000·i + …).

Sizes: 10σ by the rule of ``discrepancy_heldout`` (known-shape SNR of the
binned shape; the norm against the white noise for the ringing and the ripple
line, which live above the bins' band; the expected likelihood ratio for the
growing noise variance).
"""

from __future__ import annotations

import math

import discrepancy_scenarios as scenarios
import numpy as np
from discrepancy_heldout import FreshProfile, HeldOutSet, Unknown, scheduled_profile
from scipy.signal import lfilter

# --- the procedures ---------------------------------------------------------------------------

W1_FS_HZ, W1_DURATION_S = 120.0, 1320.0
W1_HELD_C, W1_ROOM_C = 35.0, 22.0
W1_OPEN_TAU_S, W1_CLOSE_TAU_S = 50.0, 120.0
#: (door opened s, door closed s)
W1_DOOR_S = ((300.0, 345.0), (840.0, 885.0))
W1_LADDER = tuple((sign * r, 6.0) for r in (10.0, 30.0, 100.0, 300.0) for sign in (1.0, -1.0))
W1_STARTS_S = tuple(20.0 + 120.0 * k for k in range(11))


def w1_temp_c(t_s: np.ndarray) -> np.ndarray:
    """35 °C held; each door opening pulls the air towards the 22 °C room (τ 50 s) until the door is shut,
    then the controller brings it back (a first-order recovery, τ 120 s). Continuous, with corners."""
    events = [(0.0, W1_HELD_C, W1_CLOSE_TAU_S)]
    for opened, closed in W1_DOOR_S:
        events += [(opened, W1_ROOM_C, W1_OPEN_TAU_S), (closed, W1_HELD_C, W1_CLOSE_TAU_S)]
    temp = np.full(t_s.size, W1_HELD_C)
    level = W1_HELD_C
    for k, (start, target, tau) in enumerate(events):
        end = events[k + 1][0] if k + 1 < len(events) else math.inf
        inside = (t_s >= start) & (t_s < end)
        temp[inside] = target + (level - target) * np.exp(-(t_s[inside] - start) / tau)
        level = target + (level - target) * math.exp(-(end - start) / tau) if end < math.inf else level
    return temp


def _w1() -> scenarios.Profile:
    """22 min at 120 Hz on ``w1_temp_c``; every 2 min ±10, ±30, ±100, ±300 deg/s dwells of 6 s, 500 deg/s²."""
    return scheduled_profile(W1_DURATION_S, W1_FS_HZ, w1_temp_c, W1_LADDER, W1_STARTS_S, 500.0)


W2_FS_HZ, W2_DURATION_S = 3.0, 17100.0
#: (time s, °C): cold soak, 0.6 °C/min ramp, hot soak, 3 °C/min cool, final hold
W2_TEMP_KNOTS = ((0.0, -40.0), (1800.0, -40.0), (12800.0, 70.0), (14600.0, 70.0), (15500.0, 25.0),
                 (17100.0, 25.0))
W2_BLOCK = ((0.5, 30.0), (-0.5, 30.0), (5.0, 30.0), (-5.0, 30.0), (50.0, 30.0), (-50.0, 30.0),
            (200.0, 30.0), (-200.0, 30.0), (2.0, 180.0))
W2_BLOCK_STARTS_S = (600.0, 3300.0, 6000.0, 8700.0, 11400.0, 14100.0, 15900.0)


def w2_temp_c(t_s: np.ndarray) -> np.ndarray:
    """−40 °C for 30 min, 0.6 °C/min to 70 °C, 30 min there, 3 °C/min down to 25 °C, held to the end."""
    times, temps = zip(*W2_TEMP_KNOTS, strict=True)
    return np.interp(t_s, times, temps)


def _w2() -> scenarios.Profile:
    """4.75 h at 3 Hz on ``w2_temp_c``; every 45 min (and once in the final hold) ±0.5, ±5, ±50, ±200 deg/s
    dwells of 30 s and a 2 deg/s full turn (20 deg/s²); static otherwise (about 83 % of the record)."""
    return scheduled_profile(W2_DURATION_S, W2_FS_HZ, w2_temp_c, W2_BLOCK, W2_BLOCK_STARTS_S, 20.0)


W3_FS_HZ, W3_DURATION_S = 24.0, 4500.0
W3_MEAN_FROM_C, W3_MEAN_TO_C, W3_AMPLITUDE_C, W3_PERIOD_S = 18.0, 30.0, 12.0, 1500.0
W3_BLOCK = ((3.0, 8.0), (-3.0, 8.0), (45.0, 8.0), (-45.0, 8.0), (180.0, 8.0), (-180.0, 8.0), (7.5, 48.0))
W3_BLOCK_STARTS_S = tuple(30.0 + 300.0 * k for k in range(15))


def w3_temp_c(t_s: np.ndarray) -> np.ndarray:
    """A ±12 °C sine of period 25 min around a mean drifting 18 → 30 °C (a cycling test whose mean the
    chamber lets creep): up to 3 °C/min, never held."""
    mean = W3_MEAN_FROM_C + (W3_MEAN_TO_C - W3_MEAN_FROM_C) * t_s / W3_DURATION_S
    return mean + W3_AMPLITUDE_C * np.sin(2.0 * math.pi * t_s / W3_PERIOD_S)


def _w3() -> scenarios.Profile:
    """75 min at 24 Hz on ``w3_temp_c``; every 5 min ±3, ±45, ±180 deg/s dwells of 8 s and a 7.5 deg/s
    full turn (150 deg/s²)."""
    return scheduled_profile(W3_DURATION_S, W3_FS_HZ, w3_temp_c, W3_BLOCK, W3_BLOCK_STARTS_S, 150.0)


# --- structure outside the catalogue -------------------------------------------------------------

def _unit_time(p: scenarios.Profile) -> np.ndarray:
    return p.t_s / p.t_s[-1]


def _angle_deg(p: scenarios.Profile) -> np.ndarray:
    """Table angle θ = ∫ω dt (deg), 0 at the start."""
    return np.cumsum(p.table_rate_dps) / p.fs_hz


def _temp_rate_c_per_min(p: scenarios.Profile) -> np.ndarray:
    return np.gradient(p.chamber_temp_c, p.t_s) * 60.0


def _dark_current(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """2^((T − 25 °C)/10): a photodiode's dark current doubles every ~10 °C and the demodulator passes part
    of it as a bias (exponential in T; no polynomial of low order follows it over a wide span)."""
    return np.exp2((p.chamber_temp_c - 25.0) / 10.0)


def _blower(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """|dT/dt| (°C/min): the chamber runs its blower at high speed whenever it drives a change, heating or
    cooling; the airflow's vibration is rectified into a bias of one sign."""
    return np.abs(_temp_rate_c_per_min(p))


NOTCH_DPS, NOTCH_WIDTH_DPS = 40.0, 10.0


def _sf_notch(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·exp(−½((|ω| − 40)/10)²): near 40 deg/s the drive excites the fixture's resonance and the coning
    it adds opposes the rate, so the scale factor dips in that band only (odd in ω)."""
    x = (np.abs(p.table_rate_dps) - NOTCH_DPS) / NOTCH_WIDTH_DPS
    return p.table_rate_dps * np.exp(-0.5 * x * x)


COOLING_TAU_S = 480.0


def _cooling_relaxation(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """max(0, −dT/dt) through a first-order memory of τ 8 min: moisture re-adsorbs on the coil's potting
    only while it cools, and the strain it brings relaxes slowly; heating does nothing."""
    a = math.exp(-1.0 / (COOLING_TAU_S * p.fs_hz))
    return lfilter([1.0 - a], [1.0, -a], np.maximum(0.0, -_temp_rate_c_per_min(p)))


def _angle_turned(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """∫|ω| dt in turns: the slip-ring brushes wear with every turn, either way, and their contact
    potential on the gyro's supply drifts with it (never back: unlike a net-turns wind-up)."""
    return np.cumsum(np.abs(p.table_rate_dps)) / p.fs_hz / 360.0


def _sf_hops(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω × three steps of random sign at random moments: the source's mean wavelength hopping between
    modes moves the scale factor, seen only while the table turns."""
    times = np.sort(rng.uniform(0.1, 0.9, size=3)) * p.t_s[-1]
    levels = np.concatenate([[0.0], np.cumsum(rng.choice([-1.0, 1.0], size=3))])
    return p.table_rate_dps * levels[np.searchsorted(times, p.t_s, side="right")]


def _noise_growth(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """Relative white-noise variance t/t_end: the source's power fading through the record, so the shot and
    intensity noise referred to rate grow steadily (no step, no burst)."""
    return _unit_time(p)


RING_HZ, RING_DAMPING = 1.3, 0.06


def _servo_ringing(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω_table − ω_logged for a table whose servo follows the logged (commanded) rate as a second-order
    system (1.3 Hz, ζ 0.06, unit gain at DC): it lags through each slew and rings after it; the gyro
    senses the real motion, the log holds the command."""
    w = 2.0 * math.pi * RING_HZ / p.fs_hz
    r = math.exp(-RING_DAMPING * w)
    a = [1.0, -2.0 * r * math.cos(w), r * r]
    start = p.table_rate_dps[0]
    actual = lfilter([sum(a)], a, p.table_rate_dps - start) + start
    return actual - p.table_rate_dps


def _sf_ageing(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """ω·t/t_end: the source's wavelength ageing moves the scale factor steadily in time, whatever the
    temperature (a temperature law cannot follow it where T holds or turns back)."""
    return p.table_rate_dps * _unit_time(p)


HEAT_TAU_S, COOL_TAU_S = 90.0, 450.0


def _asymmetric_lag(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """T_s − T_c for a sensor that follows the air with τ 90 s while it warms and 450 s while it cools
    (the chamber's heater blows at the mount, its refrigeration coil does not); the tempco acts on T_s."""
    up, down = math.exp(-1.0 / (HEAT_TAU_S * p.fs_hz)), math.exp(-1.0 / (COOL_TAU_S * p.fs_hz))
    temp = p.chamber_temp_c.tolist()
    out, ts = np.empty(len(temp)), temp[0]
    for i, tc in enumerate(temp):
        a = up if tc > ts else down
        ts = a * ts + (1.0 - a) * tc
        out[i] = ts - tc
    return out


RIPPLE_PER_FS = 0.137


def _warm_ripple(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """sin(2π·0.137·fs·t)·(T − T_min)/span: a switching regulator's ripple, aliased by the sampling, whose
    amplitude grows as its capacitors warm (a line, but not a stationary one)."""
    temp = p.chamber_temp_c
    return np.sin(2.0 * math.pi * RIPPLE_PER_FS * p.fs_hz * p.t_s) * (temp - temp.min()) / np.ptp(temp)


CABLE_PHASE_DEG = 30.0


def _cable_tilt(p: scenarios.Profile, rng: np.random.Generator) -> np.ndarray:
    """sign(sin(θ − 30°)): the cable bundle rests on the table top over half a turn and hangs free over the
    other, tilting it one way or the other, so Earth's horizontal rate enters as a square wave in θ."""
    return np.sign(np.sin(np.radians(_angle_deg(p) - CABLE_PHASE_DEG)))


DARK = "bias doubling every 10 °C (2^((T − 25 °C)/10): a dark current)"
BLOWER = "bias ∝ |dT/dt| (the chamber's blower, heating or cooling)"
NOTCH = "scale-factor dip in a band of rates (ω·Gaussian in |ω| at 40 ± 10 deg/s)"
COOLING = "bias relaxing (τ 8 min) after cooling only (lagged max(0, −dT/dt))"
TURNED = "bias ∝ total angle turned ∫|ω| dt (brush wear)"
SF_AGE = "scale factor ageing in time (ω·t)"
ASYM_LAG = "sensor lagging the air asymmetrically (τ 90 s warming, 450 s cooling; T_s − T_c)"
GROWTH = "white-noise variance growing linearly through the record"

UNKNOWN: dict[str, Unknown] = {
    DARK: Unknown(_dark_current),
    BLOWER: Unknown(_blower),
    NOTCH: Unknown(_sf_notch),
    COOLING: Unknown(_cooling_relaxation),
    TURNED: Unknown(_angle_turned),
    "scale-factor hops: three steps of random sign at random moments": Unknown(_sf_hops),
    GROWTH: Unknown(_noise_growth, "noise"),
    "table servo ringing after every rate change (second order, 1.3 Hz, ζ 0.06)": Unknown(_servo_ringing, "white"),
    SF_AGE: Unknown(_sf_ageing),
    ASYM_LAG: Unknown(_asymmetric_lag),
    "ripple line at 0.137·fs whose amplitude follows temperature": Unknown(_warm_ripple, "white"),
    "square wave in the table angle (sign sin(θ − 30°): cable tilt)": Unknown(_cable_tilt),
    f"temp_rate_bias + {BLOWER}": Unknown(_blower, with_effect="temp_rate_bias"),
    f"sf_nonlinearity_cubic + {NOTCH}": Unknown(_sf_notch, with_effect="sf_nonlinearity_cubic"),
    f"bias_ramp + {GROWTH}": Unknown(_noise_growth, "noise", with_effect="bias_ramp"),
}

PROFILES: dict[str, FreshProfile] = {
    # 35 °C with two dips to 27 °C: the dark current's exponential is a tempco plus a quadratic there (0.5σ
    # of 10 left beside bias_temp_quadratic); the same ladder every 2 min turns the angle at a steady
    # average pace, so the angle turned is a ramp (0.9σ beside bias_ramp): both left out, run on W2
    # thermal_lag is sized at the sizing's floor τ 1 s here, a 16σ signature (the SF tempco at 300 deg/s
    # through the door's 15 °C/min fall; 10σ would need τ ≈ 0.6 s)
    "W1": FreshProfile("W1 (22 min, 120 Hz, 35 °C held, the door opened twice for 45 s: the air falls "
                       "towards 22 °C with τ 50 s and recovers with τ 120 s; every 2 min ±10, ±30, ±100, "
                       "±300 deg/s dwells of 6 s, 500 deg/s²)",
                       _w1, {"warmup_transient": {"tau_s": 150.0}, "table_angle_harmonic": {"phase_deg": 75.0},
                             "periodic_interference": {"freq_hz": 23.9}},
                       15.0, (20.0, 200.0), 0.4, catalogue_alike=(DARK, TURNED)),
    # −40 → 70 °C: the dark current spans a factor 2^11 (4.8σ of 10 left beside bias_temp_quadratic); rate
    # blocks at uneven times and none in the cool make the angle turned a staircase (4.3σ beside bias_ramp)
    "W2": FreshProfile("W2 (4.75 h, 3 Hz, 30 min at −40 °C, 0.6 °C/min to 70 °C, 30 min there, 3 °C/min "
                       "down to 25 °C, held; every 45 min and once in the final hold ±0.5, ±5, ±50, "
                       "±200 deg/s dwells of 30 s and a 2 deg/s full turn, 20 deg/s², static otherwise)",
                       _w2, {"warmup_transient": {"tau_s": 2400.0}, "table_angle_harmonic": {"phase_deg": -135.0},
                             "periodic_interference": {"freq_hz": 0.71}},
                       0.7, (100.0, 1200.0), 2.5),
    # 9–39 °C: the dark current is nearly a quadratic (1.9σ of 10 left), the angle turned (a block every
    # 5 min) nearly a ramp (1.0σ): both left out, run on W2
    # thermal_lag: τ 1.26 s at 10σ; the 5σ row stops at the sizing's floor τ 1 s, an 8σ signature
    "W3": FreshProfile("W3 (75 min, 24 Hz, a ±12 °C sine of period 25 min around a mean drifting "
                       "18 → 30 °C; every 5 min ±3, ±45, ±180 deg/s dwells of 8 s and a 7.5 deg/s full "
                       "turn, 150 deg/s²)",
                       _w3, {"warmup_transient": {"tau_s": 700.0}, "table_angle_harmonic": {"phase_deg": 10.0},
                             "periodic_interference": {"freq_hz": 5.3}},
                       4.0, (40.0, 400.0), 1.2, catalogue_alike=(DARK, TURNED)),
}

#: W1–W3 as a set: runs seeded 59000 + 1000·(profile index) + …, unknowns' shapes from [seed, 7171]
SET = HeldOutSet("W", PROFILES, UNKNOWN, seed_base=59000, shape_stream=7171, profile_seed_stride=1000)
