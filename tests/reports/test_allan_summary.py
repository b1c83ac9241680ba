"""The report's Allan curve is the exact estimator at every length (no block-average shortcut)."""

import numpy as np

from gyrocal.analysis.allan import summary as allan_summary
from gyrocal.analysis.allan.deviation import overlapping_adev


def test_long_records_get_the_exact_curve_not_an_approximation():
    # 400 k samples was above the old (patched) 'exact limit' and got block averages
    rng = np.random.default_rng(3)
    y = rng.standard_normal(400_000) + np.cumsum(rng.standard_normal(400_000)) * 2e-3
    curve = allan_summary.allan_curve(y, 100.0)
    assert curve.method == "fully overlapping, exact"
    exact = overlapping_adev(y, 100.0, taus_s=curve.tau_s, confidence=None, compiled=False)
    np.testing.assert_allclose(curve.adev, exact.adev, rtol=1e-12, atol=0)
    assert np.all(curve.adev_lo < curve.adev) and np.all(curve.adev < curve.adev_hi)


def test_streamed_curve_equals_the_in_memory_curve_to_the_bit(tmp_path):
    y = np.random.default_rng(4).standard_normal(300_001) + 7.0
    in_memory = allan_summary.allan_curve(y, 250.0)

    def blocks():
        for start in range(0, y.size, 65_537):  # chunks unrelated to the kernel's tiles
            yield y[start : start + 65_537]

    streamed = allan_summary.allan_curve_streamed(blocks, y.size, 250.0, tmp_dir=tmp_path)
    np.testing.assert_array_equal(streamed.tau_s, in_memory.tau_s)
    np.testing.assert_array_equal(streamed.adev, in_memory.adev)
    np.testing.assert_array_equal(streamed.edf, in_memory.edf)
    np.testing.assert_array_equal(streamed.adev_lo, in_memory.adev_lo)
