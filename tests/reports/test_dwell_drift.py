"""A dwell's worst tenth against the rest (analysis/rate/dwell.py ``segment_drift``), worked by hand."""

import numpy as np

from gyrocal.analysis.rate.dwell import segment_drift


def test_ramp_samples_at_the_start_of_a_dwell_stand_out_in_its_first_tenth():
    """Issue 28: the last 80 samples of the table's ramp (84, 84.2, … 99.8 deg/s) logged as
    the first samples of a 2500-sample dwell at 100 deg/s. They fall short of 100 by
    80 × 16 − 0.2 × (0 + … + 79) = 1280 − 632 = 648 deg/s in all, so the first tenth
    (250 samples) is 648 / 250 = 2.592 deg/s below the other nine tenths."""
    dwell = np.full(2500, 100.0)
    dwell[:80] = 84.0 + 0.2 * np.arange(80)
    drift = segment_drift(dwell)
    assert drift is not None and drift.segment == 0 and drift.segments == 10
    assert abs(drift.deviation - 2.592) < 1e-9


def test_white_noise_stays_within_its_noise_limit():
    rng = np.random.default_rng(28)
    for _ in range(20):
        drift = segment_drift(100.0 + 0.004 * rng.standard_normal(2500))
        assert drift is not None and drift.deviation < drift.noise_limit


def test_the_noise_limit_is_eight_standard_errors_of_the_difference():
    # parts of 100 samples alternating ±1 (σ² = 100/99 with ddof=1): one part vs nine parts
    dwell = np.tile([1.0, -1.0], 500)
    drift = segment_drift(dwell)
    var = 100 / 99
    assert drift is not None
    assert abs(drift.noise_limit - 8 * np.sqrt(var / 100 + var / 900)) < 1e-12


def test_too_short_to_split_is_not_judged():
    assert segment_drift(np.ones(99)) is None
    assert segment_drift(np.ones(100)) is not None
