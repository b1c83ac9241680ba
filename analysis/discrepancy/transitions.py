"""Per-sample shapes that live only in transitions: the chamber heating or cooling, the table slewing.

Two out-of-catalogue probes (probes.py) are built on them, because the
catalogue's nearest effects took their place on held-out logs (issue 29):

* a bias by the **sign of dT/dt**, zero in soaks, was named ``temp_rate_bias``
  (bias ∝ dT/dt) or ``temp_hysteresis`` (a level that persists through the soak
  after a ramp) at ≥ 0.8 in 6 of 9 runs and called unexplained in 2 of 9. On a
  profile whose ramps have different rates the sign and dT/dt separate; where
  every ramp has the same |dT/dt| they cannot, and the arbitration shares the
  probability (arbitration.excess_if_effect_true, outside_odds);
* a bias ∝ the table's **angular acceleration** dω/dt, which is non-zero only
  in slews, was named ``markov_bias`` (≥ 0.8 in 2 of 9 runs) or
  ``table_angle_harmonic``, and called unexplained in 3 of 9.

The sign needs sharp edges: the chamber trend the other dT/dt probes use is a
centred 30 s difference, which starts a ramp 15 s early and ends it 15 s late
(on 7-minute ramps 7 % of the column is wrong, which on equal-rate ramps hands a
sign-shaped bias to temp_rate_bias's exact backward difference by a Δχ² of about
7 at 10σ). So a sample counts as heating (cooling) only when the trend over the
``SIGN_WINDOW_S`` before it *and* the one after it both exceed the steady-chamber
dead band (segments.STEADY_C_PER_MIN) with that sign: within a second of the true
edges on ramps of 0.5 °C/min or faster, and zero in a soak.
"""

from __future__ import annotations

import numpy as np

from gyrocal.analysis.discrepancy.segments import STEADY_C_PER_MIN

#: Length of each one-sided difference that decides whether the chamber is heating or cooling (s).
SIGN_WINDOW_S = 15.0


def one_sided_trends_c_per_min(t_s: np.ndarray, temp_c: np.ndarray, window_s: float = SIGN_WINDOW_S
                               ) -> tuple[np.ndarray, np.ndarray]:
    """The chamber trend over the ``window_s`` before and after each sample (°C/min), by index offsets.

    Offsets in samples from the median sample period (as segments.temperature_trend_c_per_min):
    an overnight log has 10 M samples, and a per-sample search of times costs seconds.
    """
    t = np.asarray(t_s, dtype=float)
    temp = np.asarray(temp_c, dtype=float)
    n = len(t)
    if n < 2:
        return np.zeros(n), np.zeros(n)
    fs = 1.0 / float(np.median(np.diff(t)))
    k = max(1, int(round(window_s * fs)))
    idx = np.arange(n)
    before, after = np.maximum(idx - k, 0), np.minimum(idx + k, n - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        back = np.where(idx > before, (temp - temp[before]) / (t - t[before]) * 60.0, np.nan)
        ahead = np.where(after > idx, (temp[after] - temp) / (t[after] - t) * 60.0, np.nan)
    # at the record's first (last) sample only the trend after (before) it exists: it stands for both
    return np.where(np.isnan(back), ahead, back), np.where(np.isnan(ahead), back, ahead)


def heating_sign(t_s: np.ndarray, temp_c: np.ndarray, dead_band_c_per_min: float = STEADY_C_PER_MIN
                 ) -> np.ndarray:
    """+1 while the chamber heats, −1 while it cools, 0 in a soak (see the module doc for the edges)."""
    back, ahead = one_sided_trends_c_per_min(t_s, temp_c)
    heating = (back > dead_band_c_per_min) & (ahead > dead_band_c_per_min)
    cooling = (back < -dead_band_c_per_min) & (ahead < -dead_band_c_per_min)
    return heating.astype(float) - cooling.astype(float)


def angular_acceleration_dps2(t_s: np.ndarray, rate_dps: np.ndarray) -> np.ndarray:
    """dω/dt of the logged table rate (deg/s²), centred differences; zero on dwells.

    A bin mean of it is the rate change across the bin over its width, so the binned
    column is exact whatever the slews' shape between samples.
    """
    t = np.asarray(t_s, dtype=float)
    rate = np.asarray(rate_dps, dtype=float)
    if len(t) < 2:
        return np.zeros(len(t))
    return np.gradient(rate, t)
