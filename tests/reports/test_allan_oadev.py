"""Overlapping ADEV against allantools (the oracle) and NIST's published NBS14 values."""

import allantools
import numpy as np
import pytest

from gyrocal.analysis.allan.deviation import log_spaced_m, overlapping_adev

pytestmark = pytest.mark.timeout(60)


def _nbs14_1000() -> np.ndarray:
    """NIST SP 1065 §12.4: n0 = 1234567890, n_{i+1} = 16807·n_i mod 2^31−1, y_i = n_i/(2^31−1)."""
    values = [1234567890]
    for _ in range(999):
        values.append(16807 * values[-1] % 2147483647)
    return np.array(values, dtype=float) / 2147483647.0


def test_nbs14_published_overlapping_adev():
    result = overlapping_adev(_nbs14_1000(), 1.0, m=[1, 10, 100])
    published = [2.922319e-1, 9.159953e-2, 3.241343e-2]
    assert [float(f"{v:.6e}") for v in result.adev] == published
    assert result.tau_s.tolist() == [1.0, 10.0, 100.0]


def _series(kind: str, n: int, rng) -> np.ndarray:
    white = rng.standard_normal(n)
    if kind == "white":
        return 3.0 + white
    if kind == "random_walk":
        return np.cumsum(white) * 0.01
    return 11.6 + white + np.cumsum(rng.standard_normal(n)) * 0.02 + 1e-5 * np.arange(n)


@pytest.mark.parametrize("kind", ["white", "random_walk", "mixed"])
@pytest.mark.parametrize(("n", "rate_hz"), [(1000, 1.0), (20_000, 100.0), (131_071, 400.0)])
def test_equals_allantools_oadev_at_every_tau(kind, n, rate_hz):
    rng = np.random.default_rng(n + len(kind))
    y = _series(kind, n, rng)
    m = log_spaced_m(n)
    ours = overlapping_adev(y, rate_hz, m=m, confidence=None)
    taus, adev, _, ns = allantools.oadev(y, rate=rate_hz, data_type="freq", taus=m / rate_hz)
    np.testing.assert_array_equal(ours.tau_s, taus)
    np.testing.assert_array_equal(ours.n_terms, ns)
    np.testing.assert_allclose(ours.adev, adev, rtol=1e-9, atol=0)


def test_long_record_spans_chunks_and_taus_argument_matches_m():
    rng = np.random.default_rng(5)
    y = rng.standard_normal(300_001)  # several 64 k chunks, odd length
    by_tau = overlapping_adev(y, 50.0, taus_s=[0.02, 1.0, 37.0, 1500.0], confidence=None)
    taus, adev, _, _ = allantools.oadev(y, rate=50.0, data_type="freq",
                                        taus=np.array([0.02, 1.0, 37.0, 1500.0]))
    np.testing.assert_allclose(by_tau.adev, adev, rtol=1e-9)
    assert by_tau.m.tolist() == [1, 50, 1850, 75000]


def test_white_rate_noise_follows_one_over_root_tau():
    """Independent of allantools: for white samples of std s, AVAR(m) = s²/m exactly in expectation."""
    rng = np.random.default_rng(11)
    y = rng.standard_normal(400_000) * 2.0
    result = overlapping_adev(y, 1.0, m=[1, 4, 16, 64])
    expected = 2.0 / np.sqrt(result.m)
    # The 68 % interval from the EDF is the yardstick; 3.5× its half-width is a safe bound.
    half_width = (result.adev_hi - result.adev_lo) / 2
    assert np.all(np.abs(result.adev - expected) < 3.5 * half_width)


def test_log_spaced_m_is_unique_increasing_and_stops_at_a_quarter():
    m = log_spaced_m(10_000_000, count=100)
    assert m[0] == 1 and m[-1] == 2_500_000
    assert np.all(np.diff(m) > 0)
    assert 80 <= m.size <= 100


@pytest.mark.parametrize(
    ("y", "kwargs", "message"),
    [
        (np.r_[np.zeros(50), np.nan], {}, "sample 50"),
        (np.zeros((10, 2)), {}, "one-dimensional"),
        (np.zeros(3), {}, "too few"),
        (np.zeros(100), {"m": [60]}, "averaging factors"),
        (np.zeros(100), {"m": [1], "taus_s": [1.0]}, "either m or taus_s"),
    ],
)
def test_bad_input_is_named(y, kwargs, message):
    with pytest.raises(ValueError, match=message):
        overlapping_adev(y, 1.0, **kwargs)


def test_zero_rate_is_refused():
    with pytest.raises(ValueError, match="sample rate"):
        overlapping_adev(np.zeros(100), 0.0)
