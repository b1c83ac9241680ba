"""Known truths for banded_line.py: a line present in part of the record only.

Sized like line_drift's cases, by the norm of the added signal against the
nominal white noise (‖s‖/σ = ``size``), so a 10σ line has the same total
energy whichever part it lives in. Our own shapes and parameters (the held-out
sets' are not used):

* ``rate_line``: a tone at ``fraction``·fs whose amplitude follows |ω|^power
  (power 1: ∝ |ω|; a large power: essentially only at the top rates);
* ``cooling_line``: a tone present only while the chamber cools faster than
  0.2 °C/min (a fan or compressor that runs then).
"""

from __future__ import annotations

import math

import numpy as np
from discrepancy_scenarios import Profile, nominal_model

from gyrocal.analysis.discrepancy.noise_model import NoiseModel


def _scaled(shape: np.ndarray, size: float, fs_hz: float) -> np.ndarray:
    sigma = NoiseModel.of_model(nominal_model()).white_sigma_dph(fs_hz)
    return size * sigma * shape / float(np.linalg.norm(shape))


def rate_line(profile: Profile, fraction: float, size: float, power: float = 1.0,
              phase_rad: float = 0.4) -> np.ndarray:
    """A tone at fraction·fs with amplitude ∝ (|ω|/max|ω|)^power, ‖s‖ = size·σ (deg/h)."""
    envelope = (np.abs(profile.table_rate_dps) / float(np.max(np.abs(profile.table_rate_dps)))) ** power
    tone = np.sin(2.0 * math.pi * fraction * profile.fs_hz * profile.t_s + phase_rad)
    return _scaled(envelope * tone, size, profile.fs_hz)


def cooling_line(profile: Profile, freq_hz: float, size: float, rate_c_per_min: float = 0.2) -> np.ndarray:
    """A tone at ``freq_hz`` only while the chamber cools faster than ``rate_c_per_min``."""
    slope = np.gradient(profile.chamber_temp_c, profile.t_s) * 60.0
    tone = np.sin(2.0 * math.pi * freq_hz * profile.t_s + 1.1)
    return _scaled((slope < -rate_c_per_min) * tone, size, profile.fs_hz)


def constant_line(profile: Profile, freq_hz: float, size: float) -> np.ndarray:
    """A tone of constant amplitude (the catalogue's periodic_interference shape), for the contrast."""
    return _scaled(np.sin(2.0 * math.pi * freq_hz * profile.t_s), size, profile.fs_hz)
