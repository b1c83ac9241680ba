"""magnetic_sensitivity: bias += k·B with B the field along the sensitive axis (T).

Truths typed by hand: a coil of 2.0e-3 T/A at 0.5 A gives B = 1.0e-3 T; at
k = 1.0e4 deg/(h·T) (the vendor notes' unshielded FOG) that is 10 deg/h on
top of the base bias.
"""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.models.gyro_model import EffectSpec, GyroModel
from gyrocal.models.indicated import ModelInputs, effect_contribution_dph, indicated_rate

pytestmark = pytest.mark.timeout(60)


def model(k_dph_per_t: float) -> GyroModel:
    base = GyroModel(version=1, scale_factor=1.0, reference_temp_c=25.0, bias_dph=2.0)
    return base.with_effect(EffectSpec("magnetic_sensitivity", {"dph_per_t": k_dph_per_t}))


def test_bias_follows_the_field_by_the_sensitivity():
    field = [1.0e-3, 0.0, -1.0e-3, 1.0e-3]
    inputs = ModelInputs.of(np.arange(4.0), 0.0, 25.0, field_t=field)
    bias = indicated_rate(model(1.0e4), inputs).bias_dph
    np.testing.assert_allclose(bias, [12.0, 2.0, -8.0, 12.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(effect_contribution_dph(model(1.0e4), "magnetic_sensitivity", inputs),
                               [10.0, 0.0, -10.0, 10.0], atol=1e-9)


def test_without_a_field_column_the_effect_adds_nothing():
    inputs = ModelInputs.of(np.arange(4.0), 0.0, 25.0)
    np.testing.assert_allclose(indicated_rate(model(1.0e4), inputs).bias_dph, 2.0, atol=0)


def test_a_non_finite_field_is_refused_by_column_and_sample():
    with pytest.raises(ValueError, match=r"field_t: non-finite value nan at sample 2"):
        ModelInputs.of(np.arange(4.0), 0.0, 25.0, field_t=[0.0, 0.0, float("nan"), 0.0])
