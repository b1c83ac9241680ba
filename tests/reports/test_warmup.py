"""Warm-up fit and turn-on repeatability (analysis/thermal/warmup.py) against the simulator's
``warmup_transient`` (models/effects.py) with a hand-typed truth: A = 30 deg/h, τ = 60 s
on a bias of 2 deg/h; the time to a ±1 deg/h band is 60·ln 30 = 204.1 s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrocal.analysis.thermal.warmup import (
    COVERAGE_K,
    fit_warmup,
    measured_time_to_band_s,
    turn_on_repeatability,
)
from gyrocal.models.gyro_model import EffectSpec, GyroModel, NoiseParams
from gyrocal.models.gyro_sim import simulate

pytestmark = pytest.mark.timeout(120)
FS_HZ = 100.0
AMPLITUDE_DPH, TAU_S, BIAS_DPH = 30.0, 60.0, 2.0
BAND_DPH = 1.0
T_BAND_S = 60.0 * math.log(30.0)


def warmup_record(seed: int, noise: NoiseParams) -> tuple[np.ndarray, np.ndarray]:
    model = GyroModel(version=1, scale_factor=1.0, reference_temp_c=25.0, bias_dph=BIAS_DPH,
                      noise=noise).with_effect(
        EffectSpec("warmup_transient", {"amplitude_dph": AMPLITUDE_DPH, "tau_s": TAU_S}))
    t = np.arange(int(600 * FS_HZ)) / FS_HZ
    out = simulate(model, t, np.zeros(t.size), 25.0, seed=seed).gyro
    return t, out * 3600.0


def test_the_fit_recovers_the_typed_transient_within_its_uncertainty():
    t, bias = warmup_record(3, NoiseParams(arw_deg_per_rth=0.01))
    fit = fit_warmup(t, bias, bin_s=1.0)
    assert abs(fit.tau_s - TAU_S) <= COVERAGE_K * fit.u_tau_s
    assert abs(fit.amplitude_dph - AMPLITUDE_DPH) <= COVERAGE_K * fit.u_amplitude_dph
    assert abs(fit.settled_dph - BIAS_DPH) <= COVERAGE_K * fit.u_settled_dph
    t_band, u_band = fit.time_to_band_s(BAND_DPH)
    assert abs(t_band - T_BAND_S) <= COVERAGE_K * u_band and u_band < 5.0
    # the data's own crossing: within a few bins of the model's (noise 0.6/√1 s ≈ 0.6 deg/h)
    measured = measured_time_to_band_s(t, bias, fit.settled_dph, BAND_DPH, bin_s=10.0)
    assert abs(measured - T_BAND_S) <= 40.0


def test_coverage_of_tau_over_seeds_with_white_noise():
    covered = sum(abs(fit.tau_s - TAU_S) <= COVERAGE_K * fit.u_tau_s
                  for fit in (fit_warmup(*warmup_record(seed, NoiseParams(arw_deg_per_rth=0.05)))
                              for seed in range(20)))
    assert covered >= 17      # 95 % nominal: 20 draws, ≥ 17 holds with probability 0.98


def test_repeatability_is_the_sample_std_with_its_u_from_n():
    rep = turn_on_repeatability([1.0, 2.0, 3.0, 4.0, 5.0])
    assert rep.std_dph == pytest.approx(math.sqrt(2.5))
    assert rep.u_std_dph == pytest.approx(math.sqrt(2.5) / math.sqrt(8.0))
    with pytest.raises(ValueError, match="at least two"):
        turn_on_repeatability([1.0])
