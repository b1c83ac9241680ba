"""Stream plausibility: samples and counter cannot outrun wall time (numbers worked by hand)."""

import pytest

from gyrocal.instruments.gyro.plausibility import StreamPlausibility


def test_a_stream_at_its_rate_is_plausible_block_after_block():
    check = StreamPlausibility(2000.0, speed=1.0, slack_s=0.0, slack_frames=0)
    check.start(100.0)
    for i in range(1, 11):                     # 500 samples each 0.25 s: exactly 2 kHz
        assert check.check(100.0 + 0.25 * i, 500, 500 * (i - 1), 500 * i - 1) is None


def test_forty_thousand_samples_in_a_tenth_of_a_second_is_stale_data():
    """The --speed 1 bug: a 20 s step at 2 kHz logged in 0.1 s wall."""
    check = StreamPlausibility(2000.0, speed=1.0)
    check.start(0.0)
    bad = check.check(0.1, 40_000, 0, 39_999)
    assert bad is not None and "stale" in bad.reason
    # allowed = 2000 × (0.1 + 0.05 slack) × 1.05 + 16 = 331 frames
    assert bad.allowed_frames == pytest.approx(331.0)


def test_speed_scales_the_frames_a_wall_second_may_carry():
    check = StreamPlausibility(2000.0, speed=20.0, slack_s=0.0, slack_frames=0)
    check.start(0.0)
    assert check.check(1.0, 40_000, 0, 39_999) is None        # 20 × 2000 frames in 1 s wall
    assert check.check(1.2, 20_000, 40_000, 59_999) is not None  # 60,000 > 1.2 × 40,000 × 1.05


def test_a_counter_jump_beyond_time_is_bad_even_with_few_samples():
    check = StreamPlausibility(1000.0, speed=1.0, slack_s=0.0, slack_frames=100)
    check.start(0.0)
    assert check.check(1.0, 1000, 0, 999) is None
    bad = check.check(2.0, 10, 5000, 5009)                     # index 5009 after 2 s: max 2200
    assert bad is not None and "counter" in bad.reason and bad.frame_span == 5010


def test_start_resets_the_account():
    check = StreamPlausibility(1000.0, slack_s=0.0, slack_frames=0)
    check.start(0.0)
    assert check.check(1.0, 1000, 0, 999) is None
    check.start(10.0)
    assert check.check(10.5, 500, 0, 499) is None
    assert check.check(10.6, 200, 500, 699) is not None        # 700 > 0.6 × 1050


def test_frames_sampled_before_the_table_was_at_rate_are_stale():
    """Issue 28: 500 Hz at 20x is 10,000 frames a wall second. The table was confirmed at rate
    0.07 s wall before the flush (its settle, then the flush); 0.01 s after the flush at most
    10,000 × (0.01 + 0.07) × 1.05 + 16 = 856 frames can have been sampled since. 1500 means
    frames from the table's acceleration, before the readback confirmed it at rate."""
    check = StreamPlausibility(500.0, speed=20.0)
    check.start(10.0, since_wall_s=9.93)
    assert check.check(10.01, 785, 0, 784) is None           # 785 <= 856: after the readback
    check.start(10.0, since_wall_s=9.93)
    bad = check.check(10.01, 1500, 0, 1499)                    # 650 frames before the readback
    assert bad is not None and "stale" in bad.reason
    assert bad.allowed_frames == pytest.approx(856.0)


def test_the_counter_counts_lost_frames_as_time_taken():
    """Frames lost in a burst of stale ones still advanced the gyro's counter (its sample clock)."""
    check = StreamPlausibility(2000.0, speed=1.0)
    check.start(0.0, since_wall_s=-1.0)                         # allowed at 0.1 s: 2326
    bad = check.check(0.1, 1000, 0, 2999)                      # 1000 frames kept, 3000 elapsed
    assert bad is not None and "counter" in bad.reason and bad.frame_span == 3000


def test_a_confirmation_after_the_flush_counts_from_the_flush():
    check = StreamPlausibility(1000.0, slack_s=0.0, slack_frames=0)
    check.start(5.0, since_wall_s=6.0)                          # clamped to the flush
    assert check.allowed_frames(6.0) == pytest.approx(1050.0)
