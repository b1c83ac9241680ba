"""The whole-record Markov likelihood (reports/discrepancy/markov_likelihood.py), checked
against what our code did not produce: the dense Gaussian likelihood of the covariance
matrix (scipy), and the truth of simulated records."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import toeplitz
from scipy.stats import multivariate_normal

from gyrocal.models.noise import GaussMarkov, WhiteRateNoise
from gyrocal.reports.discrepancy.markov_likelihood import (
    ar1_white_loglik,
    bin_means,
    fit_markov,
    white_loglik,
)


@pytest.mark.parametrize(("phi", "sigma2", "r"), [(0.9, 2.0, 0.5), (0.995, 0.3, 1.0),
                                                  (0.2, 1.0, 1e-3), (0.999, 1e-6, 1.0)])
def test_kalman_loglik_equals_the_dense_gaussian_likelihood(phi, sigma2, r):
    rng = np.random.default_rng(3)
    n = 400
    cov = sigma2 * toeplitz(phi ** np.arange(n)) + r * np.eye(n)
    y = rng.multivariate_normal(np.zeros(n), cov)
    dense = multivariate_normal(np.zeros(n), cov).logpdf(y)
    assert ar1_white_loglik(y, phi, sigma2, r) == pytest.approx(dense, rel=1e-9, abs=1e-6)
    assert white_loglik(y) == pytest.approx(
        multivariate_normal(np.zeros(n), np.mean(y * y) * np.eye(n)).logpdf(y), rel=1e-9)


@pytest.mark.parametrize(("tau_s", "seed"), [(10.0, 1), (100.0, 2), (300.0, 3)])
def test_a_markov_bias_is_found_over_a_whole_record(tau_s, seed):
    """The issue's case (σ 0.3 deg/h, τ 300 s) and the ends of its τ range, 2 h at 20 Hz,
    white noise 2.7 deg/h per sample on top (ARW 0.01 deg/√h)."""
    fs = 20.0
    n = int(2 * 3600 * fs)
    data = (GaussMarkov(0.3, tau_s, fs, seed=seed).generate(n)
            + WhiteRateNoise(0.01, fs, seed=seed + 10).generate(n))
    found = fit_markov(data, fs)
    assert found.lr > 100.0
    assert found.sigma_dph == pytest.approx(0.3, rel=0.25)
    assert found.tau_s == pytest.approx(tau_s, rel=0.5)


def test_white_records_rarely_look_markov():
    """20 white records: the statistic stays small (the threshold is calibrated on these)."""
    fs = 20.0
    n = int(3600 * fs)
    lrs = [fit_markov(WhiteRateNoise(0.01, fs, seed=500 + s).generate(n), fs).lr
           for s in range(20)]
    assert max(lrs) < 20.0, sorted(lrs)
    assert np.median(lrs) < 3.0


def test_bin_means_drop_the_short_last_bin():
    assert bin_means(np.arange(10.0), 2.0, 1.5).tolist() == [1.0, 4.0, 7.0]
