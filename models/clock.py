"""One clock for the orchestrator and the simulated instruments.

Overnight procedures must dry-run in seconds with the *same* driver and
orchestrator code that runs against hardware. The only thing that differs is
the clock: a :class:`RealClock` follows the wall clock (optionally sped up),
a :class:`SimClock` is advanced by whoever would otherwise wait — the
orchestrator's ``sleep`` while it waits for a chamber, or the simulated gyro as
its frames are consumed. Simulators evaluate their physics at ``now_s()``.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol


class Clock(Protocol):
    """What every time consumer needs: the current time and a way to wait."""

    def now_s(self) -> float:
        """Seconds since the clock's epoch (the start of the session)."""

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` seconds of this clock's time."""

    @property
    def simulated(self) -> bool:
        """True when time only moves because someone advances it."""


class RealClock:
    """Wall-clock time, optionally scaled by ``speed`` (1 = real time)."""

    def __init__(self, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        self.speed = float(speed)
        self._t0 = time.monotonic()

    @property
    def simulated(self) -> bool:
        return False

    def now_s(self) -> float:
        return (time.monotonic() - self._t0) * self.speed

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            time.sleep(dt_s / self.speed)

    def wait_until(self, t_s: float) -> None:
        """Block until the clock reads at least ``t_s`` (used to pace streams)."""
        self.sleep(t_s - self.now_s())


class SimClock:
    """Simulated time: it moves only when :meth:`advance_to` or :meth:`sleep` is called.

    Thread-safe and monotonic. Several producers may advance it (the gyro
    stream while frames are read, the orchestrator while it waits); time is
    the maximum of what they asked for, so nobody moves it backwards.
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._now_s = float(start_s)
        self._cond = threading.Condition()

    @property
    def simulated(self) -> bool:
        return True

    def now_s(self) -> float:
        with self._cond:
            return self._now_s

    def advance_to(self, t_s: float) -> float:
        """Move time forward to ``t_s`` (no-op if already later); returns the new time."""
        with self._cond:
            if t_s > self._now_s:
                self._now_s = float(t_s)
                self._cond.notify_all()
            return self._now_s

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            with self._cond:
                self._now_s += float(dt_s)
                self._cond.notify_all()

    def wait_until(self, t_s: float, timeout_s: float | None = None) -> bool:
        """Block (in wall time) until someone advances the clock to ``t_s``.

        Simulated producers that must not run ahead of their consumer use it.
        Returns False on timeout.
        """
        with self._cond:
            return self._cond.wait_for(lambda: self._now_s >= t_s, timeout=timeout_s)


def make_clock(speed: float | str | None) -> RealClock | SimClock:
    """``"max"`` or None gives simulated time; a number gives (scaled) real time."""
    if speed is None or speed == "max":
        return SimClock()
    try:
        value = float(speed)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--speed must be a number > 0 or 'max', got {speed!r}") from exc
    return RealClock(value)
