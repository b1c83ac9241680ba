"""The precomputed input history changes nothing: the equation gives the same bits with it."""

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.models.gyro_model import EffectSpec
from gyrocal.models.indicated import indicated_rate, input_history


@pytest.mark.parametrize("effect", [
    None,
    EffectSpec("temp_hysteresis", {"dph": 0.3}),
    EffectSpec("table_angle_harmonic", {"amplitude_dph": 0.2, "phase_deg": 30.0}),
    EffectSpec("temp_rate_bias", {"dph_per_c_per_min": 0.1}),
    EffectSpec("thermal_lag", {"tau_s": 100.0}),
])
def test_history_gives_bit_identical_rates(effect):
    profile = scenarios.procedure_profile(duration_s=3600.0, fs_hz=5.0)
    model = scenarios.true_base(scenarios.nominal_model())
    if effect is not None:
        model = model.with_effect(effect)
    plain = indicated_rate(model, profile.inputs).rate_dps
    cached = indicated_rate(model, profile.inputs, history=input_history(profile.inputs)).rate_dps
    np.testing.assert_array_equal(plain, cached)
