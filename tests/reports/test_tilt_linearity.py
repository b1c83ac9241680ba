"""Tilt-sensor static analysis against truths worked by hand."""

import numpy as np
import pytest

from gyrocal.analysis.environment.tilt_linearity import (
    POINTS_30_DEG,
    POINTS_90_DEG,
    lateral_sensitivity_pct,
    linearity,
    zero_stability,
)


def test_the_vendor_angle_points():
    assert POINTS_90_DEG == (-90, -75, -60, -45, -30, -15, 0, 15, 30, 45, 60, 75, 90)
    assert POINTS_30_DEG[:3] == (-30, -25, -20) and len(POINTS_30_DEG) == 13


def test_a_perfect_sensor_of_sensitivity_2_and_offset_0_1():
    out = [2.0 * np.sin(np.radians(a)) + 0.1 for a in POINTS_90_DEG]
    r = linearity(POINTS_90_DEG, out)
    assert r.sensitivity == pytest.approx(2.0) and r.zero_output == pytest.approx(0.1)
    assert r.linearity_pct_fs == pytest.approx(0.0, abs=1e-12)


def test_linearity_is_the_largest_residual_over_the_span():
    # output = a + 0.01·a³ at a = sin θ over ±90°: by hand the LS line of a³ on the 13
    # points is c·a with c = Σa⁴/Σa², so the residual at ±1 g is 0.01·(1 − c)
    a = np.sin(np.radians(POINTS_90_DEG))
    c = np.sum(a**4) / np.sum(a**2)
    r = linearity(POINTS_90_DEG, a + 0.01 * a**3)
    assert r.sensitivity == pytest.approx(1 + 0.01 * c)
    worst = np.max(np.abs(0.01 * (a**3 - c * a)))
    assert r.linearity_pct_fs == pytest.approx(worst / (2 * r.sensitivity) * 100)


def test_lateral_sensitivity_and_zero_stability():
    cross = [0.02 * np.sin(np.radians(a)) for a in POINTS_90_DEG]   # 2 % of K = 1
    assert lateral_sensitivity_pct(POINTS_90_DEG, cross, 1.0) == pytest.approx(2.0)
    assert zero_stability([0.0, 2e-4, -2e-4, 0.0], 2.0) == pytest.approx(np.std([0, 2e-4, -2e-4, 0], ddof=1) / 2)
    with pytest.raises(ValueError):
        linearity([0, 1], [0, 1])
