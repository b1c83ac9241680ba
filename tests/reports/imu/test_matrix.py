"""The IMU matrix fit against a known truth, built here without the simulator.

Dwell means are written straight from the measurement equation of the
vendor notes (seeds/003): output = b + S·u·(ω + Ω_v) + noise, with a matrix S
typed in below, so the fit is checked against numbers our simulator never
touched. The stated standard uncertainties are checked by their coverage
over many noise draws.
"""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.analysis.imu.matrix import ImuDwell, compensate, fit_temperature
from gyrocal.models.imu_model import Mounting, vertical_earth_rate_dps

LATITUDE = 50.46
# A made-up IMU: scale factors 1 ± a few hundred ppm, cross terms of a few hundred µrad.
S_TRUE = np.array([
    [1.000150, 1.000150 * 250e-6, 1.000150 * -120e-6],
    [0.999920 * 90e-6, 0.999920, 0.999920 * 300e-6],
    [1.000060 * -200e-6, 1.000060 * 60e-6, 1.000060],
])
B_TRUE = np.array([1.5, -2.0, 0.8]) / 3600.0        # output units (deg/s)
RATES = (10.0, 50.0, 200.0)
MOUNTINGS = (Mounting(0, 1.0), Mounting(1, 1.0), Mounting(2, 1.0))


def _dwells(rng: np.random.Generator, noise_dps: float, mountings=MOUNTINGS,
            s_true: np.ndarray = S_TRUE) -> list[ImuDwell]:
    earth = vertical_earth_rate_dps(LATITUDE)
    out = []
    for m in mountings:
        for rate in RATES:
            for sign in (1.0, -1.0):
                body = m.up_vector() * (sign * rate + earth)
                mean = B_TRUE + s_true @ body + rng.normal(0.0, noise_dps, 3)
                out.append(ImuDwell(f"{m.label}{sign * rate:+g}", 0, 20.0, 20.0, m,
                                    sign * rate, mean, 1000))
    return out


def test_noise_free_dwells_give_the_truth_to_rounding() -> None:
    fit = fit_temperature(_dwells(np.random.default_rng(0), 0.0), LATITUDE)
    np.testing.assert_allclose(fit.sensitivity, S_TRUE, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fit.bias_output, B_TRUE, rtol=0, atol=1e-13)
    # what the report states: E in rad, SF, input-referred bias with the Earth rate removed
    assert fit.misalignment_rad[0, 1] == pytest.approx(250e-6, abs=1e-12)
    assert fit.misalignment_rad[2, 0] == pytest.approx(-200e-6, abs=1e-12)
    assert fit.scale_factor[1] == pytest.approx(0.999920, abs=1e-13)
    np.testing.assert_allclose(fit.bias_dph, np.linalg.solve(S_TRUE, B_TRUE) * 3600, atol=1e-9)
    # compensation returns the body rate it was given
    body = np.array([0.0, 0.0, 123.0])
    np.testing.assert_allclose(compensate(fit.sensitivity, fit.bias_output,
                                          B_TRUE + S_TRUE @ body), body, atol=1e-10)


def test_inverted_mountings_give_the_same_matrix() -> None:
    flipped = tuple(Mounting(m.up_axis, -1.0) for m in MOUNTINGS)
    fit = fit_temperature(_dwells(np.random.default_rng(0), 0.0, flipped), LATITUDE)
    np.testing.assert_allclose(fit.sensitivity, S_TRUE, atol=1e-13)


def test_stated_uncertainties_cover_the_truth_95_percent_of_the_time() -> None:
    """Type-A u from the LS fit: |error| < t·u in ~95 % of 400 noise draws, per element."""
    rng = np.random.default_rng(2026)
    noise_dps = 2e-4
    errors, uncertainties = [], []
    for _ in range(400):
        fit = fit_temperature(_dwells(rng, noise_dps), LATITUDE)
        errors.append(fit.sensitivity - S_TRUE)
        uncertainties.append(fit.u_sensitivity)
    z = np.abs(np.array(errors)) / np.array(uncertainties)     # (400, 3, 3)
    # dof = 18 dwells − 4 unknowns = 14; two-sided 95 % t is 2.145
    covered = (z < 2.145).mean(axis=0)
    assert covered.min() > 0.92 and covered.max() < 0.98, covered
    # and the uncertainty is the right size, not merely wide: its median is near
    # the spread of the errors
    spread = np.std(np.array(errors), axis=0)
    ratio = np.median(np.array(uncertainties), axis=0) / spread
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def test_an_axis_never_mounted_up_is_undetermined_not_guessed() -> None:
    fit = fit_temperature(_dwells(np.random.default_rng(0), 1e-5, MOUNTINGS[:2]), LATITUDE)
    assert np.all(np.isnan(fit.sensitivity[:, 2]))
    assert np.all(np.isfinite(fit.sensitivity[:, :2]))


def test_one_rate_and_sign_only_is_refused() -> None:
    dwells = [d for d in _dwells(np.random.default_rng(0), 0.0) if d.rate_dps == 10.0][:3]
    with pytest.raises(ValueError, match="dwells for 4 unknowns"):
        fit_temperature(dwells, LATITUDE)


def test_asymmetry_and_nonlinearity_of_an_axis_are_seen() -> None:
    """A +500 ppm larger scale factor on positive X rates shows as +500 ppm asymmetry."""
    earth = vertical_earth_rate_dps(LATITUDE)
    dwells = []
    for m in MOUNTINGS:
        for rate in RATES:
            for sign in (1.0, -1.0):
                body = m.up_vector() * (sign * rate + earth)
                s = S_TRUE.copy()
                if m.up_axis == 0 and sign > 0:
                    s[0, 0] *= 1 + 500e-6
                dwells.append(ImuDwell("d", 0, 20.0, 20.0, m, sign * rate, B_TRUE + s @ body, 1))
    lin = fit_temperature(dwells, LATITUDE).axis_linearity(0)
    assert lin["asymmetry_ppm"] == pytest.approx(500.0, rel=0.01)
    assert lin["nonlinearity_max_ppm_fs"] > 0
    clean = fit_temperature(_dwells(np.random.default_rng(0), 0.0), LATITUDE).axis_linearity(0)
    assert abs(clean["asymmetry_ppm"]) < 1e-6
