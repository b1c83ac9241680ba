"""EDF, noise identification and confidence intervals of the Allan deviation.

The EDF and the interval are allantools' (the library serves); the tests pin the
one EDF case it leaves out, by hand and by Monte Carlo, and the interval against
NIST SP 1065 eq. 45 written out. The noise identification is hand-written for speed
and allantools' autocorr_noise_id is its oracle. Coverage is checked against the
exact Allan variance of simulated white and random-walk rate noise.
"""

import math

import allantools
import numpy as np
import pytest
from scipy import stats

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.allan.edf import (
    ONE_SIGMA_CONFIDENCE,
    chi2_interval,
    edf_greenhall,
    edf_white_angle_overlapping,
)
from gyrocal.analysis.allan.noise_id import (
    ALPHA_MAX,
    ALPHA_MIN,
    identify_alpha_from_averages,
    identify_alpha_per_m,
)

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
@pytest.mark.parametrize("n_phase", [101, 1001, 65_537, 1_000_001])
def test_edf_is_allantools_greenhall_wherever_that_is_defined(alpha, n_phase):
    for m in [1, 2, 3, 7, 10, 33, 100, 1000, n_phase // 4]:
        if 2 * m + 1 > n_phase or (alpha == 2 and 5 * m >= n_phase):
            continue  # allantools does not implement α=+2 with < 3 terms per τ
        expected = allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n_phase,
                                            overlapping=True, modified=False)
        assert edf_greenhall(alpha, 2, m, n_phase) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_white_angle_sum_equals_allantools_closed_form_where_both_apply(d):
    """The hand-written case, checked where allantools' case 4 (K > d) also holds."""
    checked = 0
    for n_phase in (41, 101, 1001, 100_001):
        for m in range(1, n_phase // (d + 2) + 1, max(1, n_phase // 400)):
            terms = n_phase - m * d
            if math.ceil(terms / m) <= d:
                continue
            expected = allantools.edf_greenhall(alpha=2, d=d, m=m, N=n_phase,
                                                overlapping=True, modified=False)
            assert edf_white_angle_overlapping(d, m, n_phase) == pytest.approx(expected, rel=1e-12)
            checked += 1
    assert checked > 150


def test_white_angle_sum_by_hand():
    # d = 2, 100 phase samples, m = 40: M = 100 − 80 = 20 terms, r = 0.5, K = 1 → no
    # correlated pairs, edf = M. m = 30: M = 40, r = 4/3, K = 2 → lag 1 only,
    # ρ₁ = C(4,3)/C(4,2) = 4/6, 1/edf = (1 + 2·(1 − 3/4)·4/9)/40 = (11/9)/40.
    assert edf_greenhall(2, 2, 40, 100) == pytest.approx(20.0, rel=1e-12)
    assert edf_greenhall(2, 2, 30, 100) == pytest.approx(40.0 * 9.0 / 11.0, rel=1e-12)


@pytest.mark.parametrize("m", [30, 40, 45])
def test_edf_near_record_length_for_white_angle_noise_matches_monte_carlo(m):
    """Where allantools raises, the EDF is checked against its definition:
    edf = 2·E[AVAR]² / Var[AVAR] over many white-angle records (Gaussian, exact in law)."""
    n_phase = 100
    rng = np.random.default_rng(m)
    phase = rng.standard_normal((40_000, n_phase))
    second = phase[:, 2 * m:] - 2.0 * phase[:, m:-m] + phase[:, : n_phase - 2 * m]
    avar = np.mean(second**2, axis=1)
    simulated = 2.0 * avar.mean() ** 2 / avar.var()
    with pytest.raises(NotImplementedError):
        allantools.edf_greenhall(alpha=2, d=2, m=m, N=n_phase, overlapping=True)
    assert edf_greenhall(2, 2, m, n_phase) == pytest.approx(simulated, rel=0.04)


def test_edf_refuses_what_does_not_converge_or_fit():
    with pytest.raises(ValueError, match="does not converge"):
        edf_greenhall(-2, 1, 4, 1000)
    with pytest.raises(ValueError, match="too few"):
        edf_greenhall(0, 2, 60, 100)
    with pytest.raises(ValueError, match="non-overlapping white angle"):
        edf_greenhall(2, 2, 40, 100, overlapping=False)


def test_chi2_interval_is_nist_eq_45():
    """Oracle: NIST SP 1065 eq. (45) written out with scipy's chi-squared quantiles."""
    dev = np.array([1.0, 0.5, 2.0])
    edf = np.array([3.0, 40.0, 1000.0])
    lo, hi = chi2_interval(dev, edf)
    tail = (1.0 - ONE_SIGMA_CONFIDENCE) / 2.0
    assert lo == pytest.approx(dev * np.sqrt(edf / stats.chi2.ppf(1.0 - tail, edf)), rel=1e-12)
    assert hi == pytest.approx(dev * np.sqrt(edf / stats.chi2.ppf(tail, edf)), rel=1e-12)
    lo95, hi95 = chi2_interval(dev, edf, 0.95)
    assert np.all(lo95 < lo) and np.all(hi95 > hi)


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


def _allantools_alpha(averages: np.ndarray) -> int:
    raw = allantools.autocorr_noise_id(averages, 1, data_type="freq", dmin=0, dmax=2)[0]
    return int(np.clip(raw, ALPHA_MIN, ALPHA_MAX))


def test_noise_identification_equals_allantools_type_for_type():
    """The hand-written identification is kept for speed (benchmarks/bench_noise_id.py);
    allantools is its oracle on every series: mixtures of types with a ramp, lengths
    from the minimum of 30 averages up."""
    rng = np.random.default_rng(27)
    compared = set()
    for trial in range(150):
        n = int(rng.choice([30, 31, 64, 200, 1000, 3000]))
        weights = rng.uniform(0.0, 0.5, 5)
        weights[trial % 5] = 1.0  # each type dominates in turn, the others blur it
        y = sum(w * _power_law(a, n, rng) / _power_law(a, n, rng).std()
                for w, a in zip(weights, [2, 1, 0, -1, -2], strict=True))
        y = y + rng.uniform(-1, 1) * np.arange(n) / n  # a ramp, which both remove
        ours = identify_alpha_from_averages(y)
        assert ours == _allantools_alpha(y), f"trial {trial}, n={n}, weights={weights}"
        compared.add(ours)
    assert compared == {2, 1, 0, -1, -2}


def test_noise_type_per_tau_equals_allantools_on_a_decimated_record():
    rng = np.random.default_rng(5)
    n = 300_000
    y = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 3e-3
    phase = np.concatenate(([0.0], np.cumsum(y - y.mean())))
    m_values = np.array([1, 3, 10, 30, 100, 300, 1000, 3000, 9000, 20_000])
    alphas = identify_alpha_per_m(phase, m_values, max_points=20_000)
    for m, alpha in zip(m_values, alphas, strict=True):
        points = phase[: min(n // m, 20_000) * m + 1 : m]
        if points.size - 1 >= 30:
            assert alpha == _allantools_alpha(np.diff(points)), f"m={m}"
        else:  # too few averages: the longest identifiable τ's type is carried forward
            assert alpha == alphas[m_values < m][-1]


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
