"""Six-position accelerometer calibration (analysis/imu/accel.py) against truths typed here."""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.analysis.imu.accel import AccStatic, compensate_force, fit_accelerometers, static_mean
from gyrocal.models.imu_model import Mounting

POSITIONS = ("+x", "+y", "+z", "-x", "-y", "-z")


def _statics(readings: dict[str, tuple[float, float, float]], u_g: float = 1e-6) -> list[AccStatic]:
    return [AccStatic(f"T01.M{p}.static", 0, 20.0, 20.0, Mounting.parse(p), np.array(r),
                      np.full(3, u_g), 1000) for p, r in readings.items()]


def test_a_hand_worked_six_position_example():
    # g = 1 (standard gravity). Accelerometer x: up 1.0015, down -0.9995 -> SF = 1.0005,
    # bias = (1.0015 - 0.9995)/2 = 0.001; it reads 0.0012 with y up and 0.0008 with y down,
    # so K_xy = 0.0002 and M_xy = 0.0002/1.0005 = 199.9 µrad.
    readings = {"+x": (1.0015, 0.0, 0.0), "-x": (-0.9995, 0.0, 0.0),
                "+y": (0.0012, 1.0, 0.0), "-y": (0.0008, -1.0, 0.0),
                "+z": (0.001, 0.0, 1.0), "-z": (0.001, 0.0, -1.0)}
    fit = fit_accelerometers(_statics(readings), 1.0, 0.0)
    assert fit.bias_g[0] == pytest.approx(0.001, abs=1e-12)
    assert fit.scale_factor[0] == pytest.approx(1.0005, abs=1e-12)
    assert fit.misalignment_rad[0, 1] == pytest.approx(0.0002 / 1.0005, abs=1e-12)
    assert fit.misalignment_rad[0, 2] == pytest.approx(0.0, abs=1e-12)
    assert fit.scale_factor[1] == pytest.approx(1.0) and fit.bias_g[1] == pytest.approx(0.0)


def test_local_gravity_scales_the_scale_factor_not_the_misalignment():
    # at 1.0004 g a perfect accelerometer reads ±1.0004: SF 1, not 1.0004
    readings = {p: tuple(Mounting.parse(p).up_vector() * 1.0004) for p in POSITIONS}
    fit = fit_accelerometers(_statics(readings), 1.0004, 5e-5)
    assert fit.scale_factor == pytest.approx([1.0, 1.0, 1.0], abs=1e-12)
    assert fit.u_scale_factor == pytest.approx([5e-5] * 3, rel=1e-3)   # the gravity term
    assert np.nanmax(np.abs(fit.misalignment_rad)) < 1e-12


# a truth typed by hand: bias (mg), SF error (ppm), misalignment M_ij (µrad)
BIAS_G = np.array([2.0, -1.5, 0.8]) * 1e-3
SF = 1.0 + np.array([300.0, -250.0, 150.0]) * 1e-6
M = np.array([[0.0, 400.0, -300.0], [200.0, 0.0, 500.0], [-150.0, 250.0, 0.0]]) * 1e-6
K = SF[:, None] * (np.eye(3) + M)


def test_stated_uncertainty_covers_the_truth_over_noise_draws():
    rng = np.random.default_rng(26)
    sigma_g = 20e-6
    inside = {"bias": 0, "sf": 0, "m": 0}
    draws = 300
    for _ in range(draws):
        readings = {p: tuple(K @ (Mounting.parse(p).up_vector() * 1.0004) + BIAS_G
                             + rng.standard_normal(3) * sigma_g) for p in POSITIONS}
        fit = fit_accelerometers(_statics(readings, u_g=sigma_g), 1.0004, 0.0)
        inside["bias"] += np.all(np.abs(fit.bias_g - BIAS_G) <= 2 * fit.u_bias_g)
        inside["sf"] += np.all(np.abs(fit.scale_factor - SF) <= 2 * fit.u_scale_factor)
        off = ~np.eye(3, dtype=bool)
        inside["m"] += np.all(np.abs(fit.misalignment_rad - M)[off] <= 2 * fit.u_misalignment_rad[off])
    # each count is "all three (six) elements inside 2u": 0.954^3 = 0.87, 0.954^6 = 0.75 at least
    # (the Birge ratio only widens); a u too small by 30 % (2u = 1.4 sigma) drops them to 0.84^3 = 0.59 and 0.84^6 = 0.35
    assert inside["bias"] / draws > 0.82 and inside["sf"] / draws > 0.82, inside
    assert inside["m"] / draws > 0.68, inside


def test_compensation_returns_the_true_force():
    f = np.array([0.3, -0.2, 0.93])
    assert compensate_force(K, BIAS_G, K @ f + BIAS_G) == pytest.approx(f, abs=1e-12)


def test_without_a_down_position_the_scale_factor_is_not_separable():
    readings = {p: (0.0, 0.0, 0.0) for p in ("+x", "+y", "+z")}
    with pytest.raises(ValueError, match="up and a down position"):
        fit_accelerometers(_statics(readings), 1.0, 0.0)


def test_static_mean_uncertainty_from_block_means():
    rng = np.random.default_rng(1)
    data = 0.5 + rng.standard_normal(40000) * 1e-3
    mean, u = static_mean(data)
    assert mean == pytest.approx(0.5, abs=3e-5)
    assert u == pytest.approx(1e-3 / np.sqrt(40000), rel=0.4)    # 19 dof: ±16 % (1σ)
