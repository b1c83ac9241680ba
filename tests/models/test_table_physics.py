"""Table physics against closed-form kinematics worked out by hand in each test."""

import numpy as np
import pytest

from gyrocal.models.clock import SimClock
from gyrocal.models.table import (
    MODE_OFF,
    TableInterlockError,
    TableLimitError,
    TableModeError,
    TablePhysics,
)

pytestmark = pytest.mark.timeout(30)


def running_table(clock: SimClock, **kwargs) -> TablePhysics:
    table = TablePhysics(clock, **{"max_rate_dps": 500.0, "max_accel_dps2": 20.0, **kwargs})
    table.close_interlock()
    table.set_mode_rate()
    return table


def test_ramp_takes_delta_rate_over_acceleration_then_holds_the_demand():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(100.0)  # 100 / 20 = 5 s ramp
    assert table.settle_time_s() == pytest.approx(5.0)
    clock.advance_to(2.5)
    assert table.rate_dps() == pytest.approx(50.0)
    clock.advance_to(4.999)
    assert table.rate_dps() < 100.0
    clock.advance_to(5.0)
    assert table.rate_dps() == 100.0
    clock.advance_to(60.0)
    assert table.rate_dps() == 100.0
    # Reversal -100 -> needs 200 / 20 = 10 s, passing through zero at 5 s.
    table.set_rate_demand_dps(-100.0)
    clock.advance_to(65.0)
    assert table.rate_dps() == pytest.approx(0.0, abs=1e-9)
    clock.advance_to(70.0)
    assert table.rate_dps() == -100.0


def test_lower_acceleration_limit_lengthens_the_ramp_and_bad_limits_are_refused():
    clock = SimClock()
    table = running_table(clock)
    table.set_accel_limit_dps2(4.0)
    table.set_rate_demand_dps(10.0)
    assert table.settle_time_s() == pytest.approx(2.5)
    for bad in (0.0, -1.0, 20.5, float("nan")):
        with pytest.raises(TableLimitError):
            table.set_accel_limit_dps2(bad)
    assert table.accel_limit_dps2 == 4.0


def test_demands_beyond_the_rate_limit_are_refused_and_change_nothing():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(500.0)  # exactly the limit is allowed
    with pytest.raises(TableLimitError, match="500"):
        table.set_rate_demand_dps(500.001)
    with pytest.raises(TableLimitError):
        table.set_rate_demand_dps(float("inf"))
    assert table.demand_dps == 500.0


def test_angle_after_a_profile_is_the_closed_form_integral():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(100.0)          # t 0..5 ramp: 0.5*20*25 = 250 deg
    clock.advance_to(20.0)                    # t 5..20 at 100: 1500 deg
    table.set_rate_demand_dps(40.0)           # t 20..23 down to 40: (100+40)/2*3 = 210 deg
    clock.advance_to(30.0)                    # t 23..30 at 40: 280 deg
    expected_deg = 250.0 + 1500.0 + 210.0 + 280.0
    assert table.angle_deg() == pytest.approx(expected_deg, rel=1e-12)
    assert table.revolutions() == int(expected_deg // 360)  # 2240 deg -> 6 turns
    assert table.position_deg() == pytest.approx(expected_deg % 360.0, abs=1e-9)


def test_negative_rotation_counts_negative_revolutions():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(-360.0)  # 18 s ramp covers -3240 deg
    clock.advance_to(18.0 + 10.0)      # then 10 s at -360: -3600 deg
    assert table.angle_deg() == pytest.approx(-6840.0)
    assert table.revolutions() == -19
    assert table.position_deg() == pytest.approx((-6840.0) % 360.0)


def test_opening_the_interlock_stops_the_table_at_its_acceleration_limit_and_refuses_motion():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(100.0)
    clock.advance_to(10.0)
    angle_at_open = table.angle_deg()
    table.open_interlock()
    assert table.mode == MODE_OFF
    clock.advance_to(12.0)
    assert table.rate_dps() == pytest.approx(60.0)
    clock.advance_to(100.0)
    assert table.rate_dps() == 0.0
    # Stopping from 100 at 20 deg/s^2 covers 100^2 / (2*20) = 250 deg.
    assert table.angle_deg() - angle_at_open == pytest.approx(250.0)
    with pytest.raises(TableInterlockError):
        table.set_rate_demand_dps(10.0)
    with pytest.raises(TableInterlockError):
        table.set_mode_rate()
    # Closing the interlock alone does not restart the table.
    table.close_interlock()
    with pytest.raises(TableModeError):
        table.set_rate_demand_dps(10.0)
    clock.advance_to(200.0)
    assert table.rate_dps() == 0.0


def test_mode_off_brings_the_table_to_rest_at_the_acceleration_limit():
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(-50.0)
    clock.advance_to(10.0)
    table.set_mode_off()
    clock.advance_to(11.0)
    assert table.rate_dps() == pytest.approx(-30.0)
    clock.advance_to(12.5)
    assert table.rate_dps() == 0.0


def test_hours_in_one_jump_equal_fine_stepping():
    demands = [(0.0, 90.0), (600.0, -45.0), (3600.0, 300.0), (7200.0, 0.0), (9000.0, 12.5)]
    end_s = 5 * 3600.0

    def run(step_s: float | None) -> tuple[float, float]:
        clock = SimClock()
        table = running_table(clock)
        for t_s, demand in demands:
            if step_s is not None:
                while clock.now_s() + step_s < t_s:
                    clock.sleep(step_s)
                    table.angle_deg()  # a query at every fine step
            clock.advance_to(t_s)
            table.set_rate_demand_dps(demand)
        if step_s is not None:
            while clock.now_s() + step_s < end_s:
                clock.sleep(step_s)
                table.rate_dps()
        clock.advance_to(end_s)
        tables.append(table)
        return table.angle_deg(), table.rate_dps()

    tables: list[TablePhysics] = []
    jump = run(None)
    fine = run(1.7)
    assert fine[1] == jump[1] == 12.5
    assert fine[0] == pytest.approx(jump[0], rel=1e-12)
    # Independent check of the jump result: piecewise closed form by hand.
    # 0: 0->90 in 4.5 s (202.5) + 595.5*90; 600: 90->-45 in 6.75 s (151.875) + 2993.25*-45;
    # 3600: -45->300 in 17.25 s (2199.375) + 3582.75*300; 7200: 300->0 in 15 s (2250) +0;
    # 9000: 0->12.5 in 0.625 s (3.90625) + (18000-9000.625)*12.5.
    expected_deg = (
        202.5 + 595.5 * 90 + 151.875 - 2993.25 * 45 + 2199.375 + 3582.75 * 300
        + 2250.0 + 3.90625 + (end_s - 9000.625) * 12.5
    )
    assert jump[0] == pytest.approx(expected_deg, rel=1e-12)
    # The kept history answers for past times too (segment lookup, not the current segment).
    at_600_deg = 202.5 + 595.5 * 90
    at_3600_deg = at_600_deg + 151.875 - 2993.25 * 45
    past = tables[0].angle_deg(np.array([3600.0, 600.0, 602.0]))
    np.testing.assert_allclose(past[:2], [at_3600_deg, at_600_deg], rtol=1e-12)
    assert tables[0].rate_dps(602.0) == pytest.approx(90.0 - 20.0 * 2.0)


def test_vectorised_block_matches_scalar_queries_and_extrapolates_the_current_ramp():
    clock = SimClock()
    table = running_table(clock)
    clock.advance_to(3.0)
    table.set_rate_demand_dps(50.0)  # ramp 3.0 .. 5.5 s
    clock.advance_to(4.0)
    frame_times_s = 4.0 + np.arange(400) * 0.01  # a block reaching past the end of the ramp
    rates = table.rate_dps(frame_times_s)
    angles = table.angle_deg(frame_times_s)
    assert rates.shape == angles.shape == frame_times_s.shape
    assert rates[-1] == 50.0 and rates[0] == pytest.approx(20.0)
    # Before the demand (t < 3 s) the table was at rest: the history answers too.
    assert table.rate_dps(np.array([0.5, 2.9])).tolist() == [0.0, 0.0]
    scalar_rates = []
    scalar_angles = []
    for t_s in frame_times_s:
        clock.advance_to(t_s)
        scalar_rates.append(table.rate_dps())
        scalar_angles.append(table.angle_deg())
    np.testing.assert_allclose(rates, scalar_rates, rtol=0, atol=1e-12)
    np.testing.assert_allclose(angles, scalar_angles, rtol=1e-13, atol=1e-12)


def test_rate_readback_noise_has_the_configured_spread_and_is_reproducible():
    def readbacks(seed: int) -> np.ndarray:
        clock = SimClock()
        table = running_table(clock, rate_noise_dps=0.01, seed=seed)
        table.set_rate_demand_dps(10.0)
        clock.advance_to(100.0)
        return np.array([table.read_rate_dps() for _ in range(4000)])

    first = readbacks(7)
    assert np.array_equal(first, readbacks(7))
    assert not np.array_equal(first, readbacks(8))
    assert first.mean() == pytest.approx(10.0, abs=4 * 0.01 / np.sqrt(4000))
    assert first.std(ddof=1) == pytest.approx(0.01, rel=0.05)


def test_asking_before_the_kept_history_is_an_error_naming_the_time():
    clock = SimClock()
    table = running_table(clock, history_segments=2)
    for t_s, demand in [(1.0, 5.0), (2.0, 6.0), (3.0, 7.0)]:
        clock.advance_to(t_s)
        table.set_rate_demand_dps(demand)
    with pytest.raises(ValueError, match="t=0.5"):
        table.rate_dps(0.5)


def test_synthesis_turns_the_position_sinusoid_and_its_exact_rate():
    """TM-8004 §4.3.4: peak position 0.5 deg at 1 Hz, initial phase 90 deg, entered at rest
    at t = 10 s. By hand: angle = a0 + 0.5 (sin(2π t' + π/2) − 1), rate = −π sin(2π t')."""
    clock = SimClock()
    table = running_table(clock)
    table.set_rate_demand_dps(10.0)          # 0.5 s ramp, then 10 deg/s
    clock.advance_to(4.0)
    table.set_rate_demand_dps(0.0)           # back to rest by 4.5 s
    clock.advance_to(10.0)
    a0 = 0.5 * 10.0 * 0.5 + 10.0 * 3.5 + 0.5 * 10.0 * 0.5   # 37.5 deg
    table.set_mode_synthesis(0.5, 1.0, 90.0)
    assert table.mode == "synthesis"
    assert table.rate_dps() == pytest.approx(0.0, abs=1e-12)     # cos(90°) = 0 at the start
    assert table.angle_deg() == pytest.approx(a0)
    clock.advance_to(10.25)
    assert table.rate_dps() == pytest.approx(-np.pi)
    assert table.angle_deg() == pytest.approx(a0 - 0.5)
    clock.advance_to(10.75)
    assert table.rate_dps() == pytest.approx(np.pi)
    assert table.angle_deg() == pytest.approx(a0 - 0.5)
    # a block of times (the simulated gyro asks this way), across the rest and the sinusoid
    times = np.array([9.0, 10.0, 10.5, 11.0 + 1.0 / 8.0])
    np.testing.assert_allclose(table.rate_dps(times),
                               [0.0, 0.0, 0.0, -np.pi * np.sin(np.pi / 4)], atol=1e-12)
    assert table.read_rate_dps() == pytest.approx(np.pi)         # readback follows it


def test_synthesis_ends_by_decelerating_from_the_sinusoids_rate():
    clock = SimClock()
    table = running_table(clock)
    table.set_mode_synthesis(0.5, 1.0, 0.0)       # rate π cos(2π t): π at the start
    clock.advance_to(1.0)
    table.set_mode_off()                          # π deg/s to rest at 20 deg/s²
    assert table.mode == MODE_OFF
    assert table.settle_time_s() == pytest.approx(1.0 + np.pi / 20.0)
    clock.advance_to(2.0)
    assert table.rate_dps() == 0.0


def test_synthesis_is_refused_beyond_the_limits_away_from_rest_or_with_the_interlock_open():
    clock = SimClock()
    table = running_table(clock)
    with pytest.raises(TableLimitError, match="deg/s"):
        table.set_mode_synthesis(0.5, 1.1, 0.0)   # 0.5 (2π 1.1)² = 23.9 deg/s² > 20
    with pytest.raises(TableLimitError):
        table.set_mode_synthesis(0.5, 0.0, 0.0)
    table.set_rate_demand_dps(5.0)
    clock.advance_to(1.0)
    with pytest.raises(TableModeError, match="not at rest"):
        table.set_mode_synthesis(0.1, 1.0, 0.0)
    table.open_interlock()
    clock.advance_to(6.0)
    with pytest.raises(TableInterlockError):
        table.set_mode_synthesis(0.1, 1.0, 0.0)
    assert table.mode == MODE_OFF


def test_position_move_cruises_at_the_rate_limit_and_stops_on_the_demand():
    """0 -> 90 deg at 10 deg/s and 20 deg/s²: 0.5 s up (2.5 deg), 8.5 s at 10 deg/s (85 deg),
    0.5 s down (2.5 deg): at rest on 90 deg at 9.5 s (hand-worked trapezoid)."""
    clock = SimClock()
    table = TablePhysics(clock, max_rate_dps=10.0, max_accel_dps2=20.0)
    table.close_interlock()
    table.set_mode_position()
    table.set_position_demand_deg(90.0)
    assert table.rate_dps(0.5) == pytest.approx(10.0)
    assert table.angle_deg(0.5) == pytest.approx(2.5)
    assert table.angle_deg(9.0) == pytest.approx(87.5)
    assert table.rate_dps(9.25) == pytest.approx(5.0)
    assert table.angle_deg(9.5) == pytest.approx(90.0) and table.rate_dps(9.5) == 0.0
    assert table.settle_time_s() == pytest.approx(9.5)
    with pytest.raises(TableModeError):
        table.set_rate_demand_dps(1.0)                # position mode takes no rate demand


def test_an_interlock_opening_mid_move_stops_the_table_from_where_it_is():
    """At 2 s of the move above (10 deg/s, 17.5 deg) the interlock opens: 0.5 s down, +2.5 deg."""
    clock = SimClock()
    table = TablePhysics(clock, max_rate_dps=10.0, max_accel_dps2=20.0)
    table.close_interlock()
    table.set_mode_position()
    table.set_position_demand_deg(90.0)
    clock.advance_to(2.0)
    table.open_interlock()
    clock.advance_to(60.0)
    assert table.angle_deg() == pytest.approx(20.0) and table.rate_dps() == 0.0
    assert table.mode == "off"
