"""EDF, noise identification and confidence intervals of the Allan deviation.

Oracles: allantools' Greenhall EDF, noise-ID and chi-squared interval
(written independently from the same papers), and the exact Allan variance of
simulated white and random-walk rate noise.
"""

import allantools
import numpy as np
import pytest

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.allan.edf import ONE_SIGMA_CONFIDENCE, chi2_interval, edf_greenhall
from gyrocal.analysis.allan.noise_id import identify_alpha_from_averages

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
@pytest.mark.parametrize("n_phase", [101, 1001, 65_537, 1_000_001])
def test_edf_equals_allantools_greenhall(alpha, n_phase):
    for m in [1, 2, 3, 7, 10, 33, 100, 1000, n_phase // 4]:
        if 2 * m + 1 > n_phase or (alpha == 2 and 5 * m >= n_phase):
            continue  # allantools does not implement α=+2 with < 3 terms per τ
        expected = allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n_phase,
                                            overlapping=True, modified=False)
        assert edf_greenhall(alpha, 2, m, n_phase) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("modified", [False, True])
def test_edf_other_estimators_equal_allantools(modified):
    for alpha in [1, 0, -1, -2]:
        for d in (2, 3):
            for m in [1, 4, 30, 300]:
                expected = allantools.edf_greenhall(alpha=alpha, d=d, m=m, N=5000,
                                                    overlapping=True,
                                                    modified=modified)
                mine = edf_greenhall(alpha, d, m, 5000, overlapping=True, modified=modified)
                assert mine == pytest.approx(expected, rel=1e-10)


def test_edf_near_record_length_for_white_angle_noise_is_finite_and_below_terms():
    edf = edf_greenhall(2, 2, 25, 100)
    assert 1.0 < edf < 100 - 2 * 25


def test_chi2_interval_equals_allantools():
    dev = np.array([1.0, 0.5, 2.0])
    edf = np.array([3.0, 40.0, 1000.0])
    lo, hi = chi2_interval(dev, edf)
    for i in range(3):
        ref_lo, ref_hi = allantools.confidence_interval(dev[i], edf[i], ONE_SIGMA_CONFIDENCE)
        assert lo[i] == pytest.approx(ref_lo, rel=1e-12)
        assert hi[i] == pytest.approx(ref_hi, rel=1e-12)


def _power_law(alpha: int, n: int, rng) -> np.ndarray:
    """Rate noise with PSD ∝ f^α by FFT shaping (α = 2 via differenced white angle)."""
    if alpha == 2:
        return np.diff(rng.standard_normal(n + 1))
    if alpha == -2:
        return np.cumsum(rng.standard_normal(n))
    spectrum = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n)
    gain = np.zeros_like(f)
    gain[1:] = f[1:] ** (alpha / 2.0)
    return np.fft.irfft(spectrum * gain, n)


@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
def test_noise_identification_matches_truth_and_allantools(alpha):
    rng = np.random.default_rng(100 + alpha)
    y = _power_law(alpha, 4000, rng)
    ours = identify_alpha_from_averages(y)
    theirs = allantools.autocorr_noise_id(y, 1, data_type="freq", dmin=0, dmax=2)[0]
    assert ours == alpha
    assert theirs == alpha


def test_noise_type_along_a_curve_follows_the_dominant_term():
    rng = np.random.default_rng(3)
    n = 200_000
    y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 0.003
    result = overlapping_adev(y, 1.0, m=[1, 4, 2_000, 5_000])
    assert result.alpha.tolist()[:2] == [0, 0]
    assert result.alpha.tolist()[2:] == [-2, -2]


def _coverage(kind: str, seeds: int, n: int, m: np.ndarray) -> np.ndarray:
    hits = np.zeros(m.size)
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        if kind == "white":
            y = rng.standard_normal(n)
            true_adev = 1.0 / np.sqrt(m)
        else:
            y = np.cumsum(rng.standard_normal(n))
            true_adev = np.sqrt((2.0 * m**2 + 1.0) / (6.0 * m))  # exact discrete random walk
        result = overlapping_adev(y, 1.0, m=m)
        hits += (result.adev_lo <= true_adev) & (true_adev <= result.adev_hi)
    return hits / seeds


@pytest.mark.parametrize("kind", ["white", "random_walk"])
def test_interval_contains_true_adev_at_its_confidence(kind):
    """68.3 % intervals over 300 seeds: binomial sd is 2.7 %, so ±10 % allows ~3.7 sd
    plus the noise-ID misclassifications that happen at the long-τ end."""
    m = np.array([1, 8, 64, 256, 1024])
    coverage = _coverage(kind, seeds=300, n=8192, m=m)
    assert np.all(np.abs(coverage - ONE_SIGMA_CONFIDENCE) < 0.10), coverage
