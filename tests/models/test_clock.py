import threading
import time

import pytest

from gyrocal.models.clock import RealClock, SimClock, make_clock


def test_sim_clock_moves_only_when_advanced_and_never_backwards():
    clock = SimClock()
    assert clock.now_s() == 0.0
    clock.sleep(3600.0)
    assert clock.now_s() == 3600.0
    assert clock.advance_to(10.0) == 3600.0
    assert clock.advance_to(7200.5) == 7200.5


def test_sim_clock_wait_until_wakes_when_another_thread_advances():
    clock = SimClock()
    woke = []
    t = threading.Thread(target=lambda: woke.append(clock.wait_until(50.0, timeout_s=5)))
    t.start()
    clock.advance_to(49.0)
    clock.advance_to(50.0)
    t.join(5)
    assert woke == [True]
    assert clock.wait_until(1e9, timeout_s=0.01) is False


def test_make_clock_parses_speed():
    assert isinstance(make_clock("max"), SimClock)
    assert isinstance(make_clock("10"), RealClock)
    with pytest.raises(ValueError, match="--speed"):
        make_clock("fast")
    with pytest.raises(ValueError):
        RealClock(0)


def test_transport_wait_is_wall_time_on_a_real_clock_and_none_on_simulated_time():
    """A transport's wait (bytes in flight after a flush) is wall time however fast a real
    clock runs, and neither waits nor moves simulated time (the simulated port drops what
    it made before a flush itself: tests/instruments/sim/test_gyro_pty.py)."""
    fast = RealClock(speed=1000.0)
    start = time.monotonic()
    fast.transport_wait(0.05)
    assert time.monotonic() - start >= 0.05          # not 0.05 / 1000
    sim = SimClock(start_s=3.0)
    start = time.monotonic()
    sim.transport_wait(5.0)
    assert time.monotonic() - start < 1.0 and sim.now_s() == 3.0
