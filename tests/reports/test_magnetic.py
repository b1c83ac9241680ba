"""Magnetic bias sensitivity against a truth worked by hand."""

import numpy as np
import pytest

from gyrocal.analysis.environment.magnetic import field_t, sensitivity


def test_slope_and_uncertainty_by_hand():
    # coil 2 mT/A at -0.5, 0, +0.5 A: -1, 0, +1 mT; bias 0.5 -/+ 0.005 deg/h -> 5 deg/(h·T)
    b = field_t([-0.5, 0.0, 0.5], 2e-3)
    assert b == pytest.approx([-1e-3, 0.0, 1e-3])
    r = sensitivity(b, [0.495, 0.5, 0.505], [0.001] * 3)
    assert r.sensitivity_dph_per_t == pytest.approx(5.0)
    assert r.bias_at_zero_dph == pytest.approx(0.5)
    # equal weights: u(slope) = u/sqrt(Σ(B − B̄)²) = 0.001/sqrt(2e-6) = 0.7071 deg/(h·T)
    assert r.u_dph_per_t == pytest.approx(0.001 / np.sqrt(2e-6))
    assert "navigation-grade" in r.grade()
    # a 1 % coil constant adds 0.05 in quadrature
    with_coil = sensitivity(b, [0.495, 0.5, 0.505], [0.001] * 3, u_coil_rel=0.01)
    assert with_coil.u_dph_per_t == pytest.approx(np.hypot(0.7071068, 0.05), rel=1e-6)


def test_an_unshielded_coil_and_bad_input():
    r = sensitivity([-1e-4, 1e-4], [-1.0, 1.0], [0.01, 0.01])
    assert r.sensitivity_dph_per_t == pytest.approx(1e4)
    assert "unshielded" in r.grade()
    with pytest.raises(ValueError, match="distinct fields"):
        sensitivity([0.0, 0.0], [1.0, 1.0], [0.1, 0.1])
