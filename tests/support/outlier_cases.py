"""Known truths for the spike test (analysis/discrepancy/outliers.py): outliers and doubled samples.

Both are added to a simulated log as extra deg/h per sample (``simulate_log``'s ``extra_dph``),
sized against the model's white-noise σ at the profile's rate. The parameters are this
module's own (not the held-out sets'):

* ``outliers_dph``: 3–8 single samples (count drawn per seed) anywhere in the record, sizes
  8σ·(1 + Pareto(1.5)) capped at 30σ (a heavy-tailed law), random signs;
* ``doubled_dph``: every ``period_s`` (4.1 s) one sample's angle increment counted twice while
  the table turns: a spike of ``fraction``·ω in that sample (``fraction`` 1: the whole
  increment; ``doubled_fraction_for`` sizes a smaller one from the spike at the top rate).
"""

from __future__ import annotations

import numpy as np
from discrepancy_scenarios import Profile, nominal_model

from gyrocal.analysis.discrepancy.noise_model import NoiseModel

#: Seconds between doubled samples (own choice).
PERIOD_S = 4.1


def white_sigma_dph(profile: Profile) -> float:
    return NoiseModel.of_model(nominal_model()).white_sigma_dph(profile.fs_hz)


def outliers_dph(profile: Profile, seed: int, low_sigma: float = 8.0, high_sigma: float = 30.0) -> np.ndarray:
    """3–8 single-sample outliers of low…high σ (heavy-tailed sizes), at random samples."""
    rng = np.random.default_rng([seed, 2930])
    n = profile.t_s.size
    count = int(rng.integers(3, 9))
    where = rng.choice(np.arange(10, n - 10), size=count, replace=False)
    sizes = np.minimum(low_sigma * (1.0 + rng.pareto(1.5, count)), high_sigma)
    extra = np.zeros(n)
    extra[where] = sizes * rng.choice([-1.0, 1.0], count) * white_sigma_dph(profile)
    return extra


def doubled_dph(profile: Profile, fraction: float = 1.0, period_s: float = PERIOD_S,
                offset_s: float = 1.3) -> np.ndarray:
    """A sample's angle increment counted (``fraction``) twice every ``period_s`` while the table turns."""
    t = profile.t_s - profile.t_s[0]
    every = np.round(np.arange(offset_s, t[-1], period_s) * profile.fs_hz).astype(int)
    every = every[every < t.size]
    extra = np.zeros(t.size)
    extra[every] = fraction * profile.table_rate_dps[every] * 3600.0
    return extra


def doubled_fraction_for(profile: Profile, top_sigma: float) -> float:
    """The fraction whose spike at the profile's largest |rate| is ``top_sigma`` white-noise σ."""
    return top_sigma * white_sigma_dph(profile) / (3600.0 * float(np.max(np.abs(profile.table_rate_dps))))
