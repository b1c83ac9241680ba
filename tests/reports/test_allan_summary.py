import numpy as np

from gyrocal.reports import allan_summary
from gyrocal.reports.allan import overlapping_adev


def test_block_average_curve_for_huge_records_tracks_the_exact_one(monkeypatch):
    rng = np.random.default_rng(3)
    y = rng.standard_normal(400_000) + np.cumsum(rng.standard_normal(400_000)) * 2e-3
    monkeypatch.setattr(allan_summary, "EXACT_LIMIT_SAMPLES", 100_000)
    approx = allan_summary.allan_curve(y, 100.0)
    assert approx.method.startswith("overlapping on block averages")
    exact = overlapping_adev(y, 100.0, taus_s=approx.tau_s, confidence=None)
    np.testing.assert_allclose(exact.tau_s, approx.tau_s)
    relative = np.abs(approx.adev / exact.adev - 1)
    assert np.median(relative) < 0.01
    assert relative.max() < 0.08
    # the interval is computed for the estimator used and still brackets it
    assert np.all(approx.adev_lo < approx.adev) and np.all(approx.adev < approx.adev_hi)


def test_overnight_sized_holds_use_the_exact_estimator():
    y = np.random.default_rng(4).standard_normal(300_000)
    curve = allan_summary.allan_curve(y, 250.0)
    assert curve.method == "overlapping (exact)"
