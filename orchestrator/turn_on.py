"""The power cycle of a turn-on step (IEEE Std 952 / IEEE Std 1431 turn-on time and warm-up).

The station's supply switches the unit off (read back off), the off time passes, the gyro's
input is flushed and the output is switched on; from that command the gyro is polled until
its first valid frame. Its arrival is known to lie within the last poll interval, so the
time to first valid data is that interval's middle with a rectangular uncertainty of half
its width (the report's U). The engine then logs the step as any other, from that frame on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from gyrocal.instruments.errors import InstrumentTimeout
from gyrocal.orchestrator.run_errors import RunFaultError

#: the unit must send its first valid frame within this long of the output-on
FIRST_FRAME_TIMEOUT_S = 30.0
#: the first-frame poll interval (clock time): the turn-on time's resolution
FIRST_FRAME_POLL_S = 0.02
#: how long (wall time) one poll waits for bytes already sent
_POLL_READ_S = 0.05
#: a dry run's poll that knows bytes are waiting: long enough for any load on the machine
_SIM_READ_S = 5.0

#: a dry run's simulated gyro: did it make bytes since the last poll?
#: (None: a real gyro, whose poll waits ``_POLL_READ_S`` of wall time)
BytesWaiting = Callable[[], bool] | None


@dataclass(frozen=True)
class PowerCycle:
    """Clock times of one power cycle (the clock of the logged ``t_s`` columns)."""

    off_clock_s: float
    on_clock_s: float             # the output-on command
    first_frame_clock_s: float    # the end of the poll interval the first frame came in
    poll_s: float

    @property
    def first_frame_after_s(self) -> float:
        """Time to first valid data: the middle of the poll interval it came in."""
        return self.first_frame_clock_s - 0.5 * self.poll_s - self.on_clock_s


def power_cycle(supply, gyro, clock, step_id: str, off_s: float,
                poll_s: float = FIRST_FRAME_POLL_S, waiting: BytesWaiting = None) -> PowerCycle:
    """Off (read back), wait ``off_s``, on, poll for the first frame; RunFaultError if the
    output does not read back off or no frame comes within FIRST_FRAME_TIMEOUT_S."""
    supply.set_output(False)
    if supply.read().output_on:
        raise RunFaultError(f"supply: {step_id}: the output reads on after switching it off")
    off_clock_s = clock.now_s()
    clock.sleep(off_s)
    gyro.flush()
    on_clock_s = clock.now_s()
    supply.set_output(True)
    first_clock_s = wait_first_frame(gyro, clock, on_clock_s, step_id, poll_s, waiting)
    return PowerCycle(off_clock_s, on_clock_s, first_clock_s, poll_s)


def wait_first_frame(gyro, clock, on_clock_s: float, what: str,
                     poll_s: float = FIRST_FRAME_POLL_S, waiting: BytesWaiting = None) -> float:
    """Poll until a valid frame arrives; the clock time at the end of the interval it came
    in. Also what the preflight does after powering the unit (its start-up delay).

    In a dry run (``waiting`` given) a poll does not race the simulated gyro's stream
    thread in wall time, which made the first frame's interval, and with it every later
    time stamp, move with the machine's load: whether the simulator made bytes in the
    interval is known, so the read waits long for them, or not at all."""
    while True:
        clock.elapse_reading(poll_s)
        timeout_s = _POLL_READ_S if waiting is None else (_SIM_READ_S if waiting() else 0.0)
        try:
            gyro.read_samples(1, timeout_s=timeout_s)
        except InstrumentTimeout:
            if clock.now_s() - on_clock_s > FIRST_FRAME_TIMEOUT_S:
                raise RunFaultError(f"gyro: {what}: no valid frame within "
                                    f"{FIRST_FRAME_TIMEOUT_S:g} s of the output-on") from None
            continue
        return clock.now_s()
