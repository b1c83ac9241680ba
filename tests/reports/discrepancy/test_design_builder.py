"""The design builder's remembered bin means and side-by-side evaluations give the same regressors
as evaluating each unit model and the zeroed model at full rate and binning their difference."""

from __future__ import annotations

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy import signatures
from gyrocal.analysis.discrepancy.segments import make_bins
from gyrocal.analysis.discrepancy.signatures import (
    DesignBuilder,
    model_columns,
    unit_model,
    zero_linear,
)
from gyrocal.models.gyro_model import EffectSpec


@pytest.mark.parametrize("parallel", [False, True])
def test_design_matches_full_rate_differences(monkeypatch, parallel):
    monkeypatch.setattr(signatures, "PARALLEL_MIN_SAMPLES", 0 if parallel else 10**12)
    prof = scenarios.procedure_profile(1500.0, 20.0, setpoints_c=(25.0, 35.0), ramps_c_per_min=(5.0,),
                                       rates_dps=(1.0, 20.0), dwell_s=15.0, static_s=60.0,
                                       slow_rate_dps=4.0, accel_dps2=10.0)
    bins = make_bins(prof.t_s, prof.fs_hz, max_bins=300)
    model = scenarios.nominal_model().with_effect(EffectSpec("thermal_lag", {"tau_s": 200.0})).with_effect(
        EffectSpec("sf_asymmetry", {"ppm": 0.0}))
    builder = DesignBuilder(prof.inputs, bins)
    design = builder.design(model)
    again = builder.design(model)            # from the remembered bin means
    zeroed = zero_linear(model)
    offset = builder.rate_dph(zeroed)
    for j, column in enumerate(model_columns(model)):
        expected = bins.mean(builder.rate_dph(unit_model(zeroed, column)) - offset)
        scale = max(np.max(np.abs(expected)), 1.0)
        assert np.max(np.abs(design.x_bins[:, j] - expected)) < 1e-9 * scale, column
    assert np.array_equal(design.x_bins, again.x_bins)
    assert np.allclose(design.offset_bins, bins.mean(offset), rtol=0, atol=1e-9 * np.max(np.abs(offset)))
