"""Joint noise-term fit on curves and data generated from a known truth."""

import math

import numpy as np
import pytest

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.allan.noise_fit import (
    MARKOV_PEAK_RATIO,
    TERM_NAMES,
    fit_noise_terms,
    markov_avar_unit,
)

pytestmark = pytest.mark.timeout(120)

FS_HZ = 10.0


def _ieee_adev_dph(tau_s, q_arcsec=0.0, n_rth=0.0, b_dph=0.0, k_rth=0.0, r_h=0.0):
    """IEEE 952 Annex C terms written in their native units, converted here step by step."""
    tau_h = tau_s / 3600.0
    q_deg = q_arcsec / 3600.0
    quant = (math.sqrt(3.0) * q_deg / tau_s) * 3600.0  # deg/s -> deg/h
    arw = n_rth / np.sqrt(tau_h)
    bias_inst = math.sqrt(2.0 * math.log(2.0) / math.pi) * b_dph
    rrw = k_rth * np.sqrt(tau_h / 3.0)
    ramp = r_h * tau_h / math.sqrt(2.0)
    return np.sqrt(quant**2 + arw**2 + bias_inst**2 + rrw**2 + ramp**2)


def test_noise_free_curve_returns_every_coefficient_in_its_units():
    truth = {"Q_arcsec": 0.7, "N_deg_per_rth": 0.003, "B_dph": 0.03,
             "K_dph_per_rth": 0.02, "R_dph_per_h": 0.01}
    tau = np.logspace(-2, 5, 80)
    adev = _ieee_adev_dph(tau, 0.7, 0.003, 0.03, 0.02, 0.01)
    fit = fit_noise_terms(tau, adev, edf=np.full(tau.size, 50.0), markov=False)
    for name in TERM_NAMES:
        assert getattr(fit, name).value == pytest.approx(truth[name], rel=1e-6), name
    np.testing.assert_allclose(fit.model_adev(tau), adev, rtol=1e-9)


def test_markov_allan_variance_has_the_published_shape():
    """IEEE 952 / Chikovani: the hump peaks at τ = 1.89·T with height 0.437·q_c·√T,
    where q_c = σ·√(2/T) is the driving-noise amplitude."""
    correlation_s = 528.0
    tau = np.logspace(1, 5, 200_001)
    avar = markov_avar_unit(tau, correlation_s)
    peak = int(np.argmax(avar))
    assert tau[peak] / correlation_s == pytest.approx(1.89, abs=0.005)
    assert abs(MARKOV_PEAK_RATIO - 1.89) < 0.005
    q_c = math.sqrt(2.0 / correlation_s)
    assert math.sqrt(avar[peak]) == pytest.approx(0.437 * q_c * math.sqrt(correlation_s), rel=2e-3)
    # Short τ: indistinguishable from rate random walk q_c²·τ/3; long τ: white, 2σ²T/τ.
    assert markov_avar_unit(np.array([1e-3]), 1.0)[0] == pytest.approx(2.0 / 3.0 * 1e-3, rel=1e-3)
    assert markov_avar_unit(np.array([1e4]), 1.0)[0] == pytest.approx(2.0 / 1e4, rel=1e-3)


def _curve(noise_truth, seed, n, parts):
    rng = np.random.default_rng(seed)
    y = np.zeros(n)
    for name, args in parts:
        y += getattr(noise_truth, name)(rng, n, FS_HZ, *args)
    return overlapping_adev(y, FS_HZ)


def _fit(result, markov="auto"):
    return fit_noise_terms(result.tau_s, result.adev, result.edf, markov=markov,
                           alpha=result.alpha)


def test_bias_instability_between_overlapping_arw_and_rrw(noise_truth):
    """N and K meet where the curve is flat, lifting its minimum: the joint fit keeps
    B within 12 % in every seed; reading B off the minimum is typically 20–38 % off
    (a 17-seed survey: joint ≤ 10.4 %, slope reading 21–38 %, one seed −27 %)."""
    b_true = 0.1
    parts = [("white_rate", (0.01,)), ("flicker_rate", (b_true,)), ("rate_random_walk", (0.3,))]
    hits = {"N_deg_per_rth": 0, "B_dph": 0, "K_dph_per_rth": 0}
    truth = {"N_deg_per_rth": 0.01, "B_dph": b_true, "K_dph_per_rth": 0.3}
    joint_errors, slope_errors = [], []
    seeds = range(5)
    for seed in seeds:
        result = _curve(noise_truth, seed, 2**19, parts)
        fit = _fit(result)
        joint_error = abs(fit.B_dph.value / b_true - 1.0)
        slope_error = abs(result.adev.min() / math.sqrt(2 * math.log(2) / math.pi) / b_true - 1.0)
        assert joint_error < 0.12
        joint_errors.append(joint_error)
        slope_errors.append(slope_error)
        for name in hits:
            estimate = getattr(fit, name)
            hits[name] += abs(estimate.value - truth[name]) <= 2.0 * estimate.stderr
    assert np.median(slope_errors) > 0.20
    assert np.median(slope_errors) > 3 * np.median(joint_errors)
    # 2σ intervals: expect ~95 %; "most seeds" = at least 3 of 5.
    assert all(count >= 3 for count in hits.values()), hits


def test_markov_hump_is_found_with_its_correlation_time(noise_truth):
    sigma_true, t_true = 0.5, 40.0
    parts = [("white_rate", (0.005,)), ("markov", (sigma_true, t_true))]
    inside_sigma = inside_t = 0
    seeds = range(4)
    for seed in seeds:
        fit = _fit(_curve(noise_truth, 50 + seed, 2**18, parts))
        assert fit.markov is not None
        assert fit.markov.tau_s.value == pytest.approx(t_true, rel=0.3)
        assert fit.markov.sigma_dph.value == pytest.approx(sigma_true, rel=0.2)
        assert fit.markov.tau_peak_s == pytest.approx(MARKOV_PEAK_RATIO * fit.markov.tau_s.value)
        inside_sigma += abs(fit.markov.sigma_dph.value - sigma_true) <= 2 * fit.markov.sigma_dph.stderr
        inside_t += fit.markov.tau_s.lo / 1.5 <= t_true <= fit.markov.tau_s.hi * 1.5
        assert fit.N_deg_per_rth.value == pytest.approx(0.005, rel=0.1)
    assert inside_sigma >= 3 and inside_t >= 3, (inside_sigma, inside_t)


def test_no_markov_term_is_added_without_a_hump(noise_truth):
    parts = [("white_rate", (0.01,)), ("rate_random_walk", (0.3,))]
    added = sum(_fit(_curve(noise_truth, 70 + s, 2**18, parts)).markov is not None
                for s in range(4))
    assert added == 0  # 0 of 17 in a survey with the documented rule


def test_quantization_and_rate_ramp_are_recovered(noise_truth):
    rng = np.random.default_rng(9)
    n = 2**18
    r_true = 2.0  # deg/h per hour
    y = (noise_truth.quantization(rng, n, FS_HZ, 0.5)
         + noise_truth.white_rate(rng, n, FS_HZ, 0.002)
         + r_true * np.arange(n) / FS_HZ / 3600.0)
    fit = _fit(overlapping_adev(y, FS_HZ), markov=False)
    assert fit.Q_arcsec.value == pytest.approx(0.5, rel=0.05)
    assert fit.R_dph_per_h.value == pytest.approx(r_true, rel=0.05)
    assert fit.N_deg_per_rth.value == pytest.approx(0.002, rel=0.15)
    assert fit.K_dph_per_rth.lo == 0.0  # no rate random walk in the data


def test_json_keys_follow_the_interface_contract():
    tau = np.logspace(-1, 4, 40)
    fit = fit_noise_terms(tau, _ieee_adev_dph(tau, n_rth=0.01, b_dph=0.05), markov=False)
    assert set(fit.to_json()) == {"Q_arcsec", "N_deg_per_rth", "B_dph", "K_dph_per_rth",
                                  "R_dph_per_h", "markov"}
    assert fit.to_json()["markov"] is None


@pytest.mark.parametrize(
    ("tau", "adev", "message"),
    [
        (np.logspace(0, 3, 10), np.r_[np.ones(9), -1.0], r"adev_dph\[9\]"),
        (np.logspace(0, 3, 10)[::-1], np.ones(10), "increasing"),
        (np.logspace(0, 3, 4), np.ones(4), "too few"),
    ],
)
def test_bad_curves_are_refused_with_the_point_named(tau, adev, message):
    with pytest.raises(ValueError, match=message):
        fit_noise_terms(tau, adev)
