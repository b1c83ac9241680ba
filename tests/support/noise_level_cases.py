"""A known truth for the noise-level test: white noise growing with |ω|, σ(ω) = σ0·(1 + k·|ω|).

The workflow's effects are sized by known-shape SNR (the χ² gain of their bin-mean
signature); a change of the noise *level* has no bin-mean signature, so it is sized by
its expected likelihood ratio instead, as ``discrepancy_scenarios.sized_markov`` sizes
a random process: per sample, 2·KL between N(0, σ(ω)²) and N(0, σ0²) is r − 1 − ln r
with r = σ(ω)²/σ0², and k is solved (bisection in log k) for a sum of snr².
"""

from __future__ import annotations

import math

import numpy as np
from discrepancy_scenarios import Profile, nominal_model

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.models.gyro_model import GyroModel


def expected_lr(k_per_dps: float, abs_rate_dps: np.ndarray) -> float:
    """E[2 ln LR] of σ0·(1 + k|ω|) against σ0 over the samples (σ0 known)."""
    r = (1.0 + k_per_dps * abs_rate_dps) ** 2
    return float(np.sum(r - 1.0 - np.log(r)))


def sized_noise_growth(snr: float, profile: Profile) -> float:
    """k (per deg/s) of σ0·(1 + k|ω|) whose expected likelihood ratio is snr²."""
    abs_rate = np.abs(profile.table_rate_dps)
    lo, hi = math.log(1e-9), math.log(10.0)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if expected_lr(math.exp(mid), abs_rate) < snr * snr:
            lo = mid
        else:
            hi = mid
    return math.exp(0.5 * (lo + hi))


def noise_growth_dph(k_per_dps: float, profile: Profile, seed: int, nominal: GyroModel | None = None
                     ) -> np.ndarray:
    """Extra white noise (deg/h per sample) that takes the model's σ0 to σ0·(1 + k|ω|).

    Independent of the simulator's own noise, so the variances add:
    σ0²·((1 + k|ω|)² − 1) more, zero at rest.
    """
    sigma0 = NoiseModel.of_model(nominal or nominal_model()).white_sigma_dph(profile.fs_hz)
    extra_sd = sigma0 * np.sqrt((1.0 + k_per_dps * np.abs(profile.table_rate_dps)) ** 2 - 1.0)
    return extra_sd * np.random.default_rng([seed, 2929]).standard_normal(len(profile.t_s))
