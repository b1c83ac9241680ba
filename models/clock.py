"""One clock for the orchestrator and the simulated instruments.

Overnight procedures must dry-run in seconds with the *same* driver and
orchestrator code that runs against hardware. The only thing that differs is
the clock: a :class:`RealClock` follows the wall clock (optionally sped up),
a :class:`SimClock` is advanced only by the controller, in its own thread —
``sleep`` while it waits for a chamber, ``elapse_reading`` while it reads a
stream. Simulators evaluate their physics at ``now_s()``, and a simulated
stream subscribes to the clock to produce exactly the frames of the time that
elapsed. Nobody else moves simulated time, so the same commands give the same
times, the same physics and (with the same seeds) the same samples, however
the threads are scheduled.

Two kinds of wait, kept apart: what the *physics* needs (a settle, a soak, a
dwell: ``sleep``, simulated time advanced on demand) and what a *transport*
needs (bytes a USB-serial adapter still holds after a flush: ``transport_wait``,
wall time on a real port). The clock decides how long each takes: on a real
clock both wait; on simulated time the first moves the clock and the second
returns at once, since every simulated port makes its bytes only in the
controller's own calls (``instruments/sim/gyro_pty.py``), so none is in flight.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Protocol

#: Called as (from_s, to_s, reading) in the advancing thread, after simulated time moved.
AdvanceListener = Callable[[float, float, bool], None]


class Clock(Protocol):
    """What every time consumer needs: the current time and a way to wait."""

    def now_s(self) -> float:
        """Seconds since the clock's epoch (the start of the session)."""

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` seconds of this clock's time."""

    def elapse_reading(self, dt_s: float) -> None:
        """Let ``dt_s`` pass while a stream is read (a real read takes that time itself)."""

    def transport_wait(self, dt_s: float) -> None:
        """Let ``dt_s`` wall seconds pass for bytes a transport has in flight (not clock time)."""

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

    def elapse_reading(self, dt_s: float) -> None:
        """Nothing to do: on real time the read itself waits for its samples."""

    def transport_wait(self, dt_s: float) -> None:
        """Sleep ``dt_s`` of wall time, unscaled by ``speed``: a port's in-flight bytes
        (an adapter's latency timer, a writer thread's last write) arrive in wall time
        however fast the clock runs."""
        if dt_s > 0:
            time.sleep(dt_s)

    def wait_until(self, t_s: float) -> None:
        """Block until the clock reads at least ``t_s`` (used to pace streams)."""
        self.sleep(t_s - self.now_s())


class SimClock:
    """Simulated time: it moves only when the controller sleeps or reads a stream.

    Thread-safe and monotonic. Listeners (simulated streams) are told of each
    advance in the advancing thread, so what a stream produces is a function
    of the controller's calls alone; ``reading`` says whether the controller
    is reading the stream over that span (every frame is wanted) or waiting
    for something else (only the most recent frames matter, as in a UART
    nobody reads).
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._now_s = float(start_s)
        self._cond = threading.Condition()
        self._listeners: list[AdvanceListener] = []

    @property
    def simulated(self) -> bool:
        return True

    def now_s(self) -> float:
        with self._cond:
            return self._now_s

    def subscribe(self, listener: AdvanceListener) -> None:
        """Call ``listener(from_s, to_s, reading)`` after every advance."""
        with self._cond:
            self._listeners.append(listener)

    def unsubscribe(self, listener: AdvanceListener) -> None:
        with self._cond:
            if listener in self._listeners:
                self._listeners.remove(listener)

    def advance_to(self, t_s: float, reading: bool = False) -> float:
        """Move time forward to ``t_s`` (no-op if already later); returns the new time."""
        with self._cond:
            before_s = self._now_s
            if t_s > before_s:
                self._now_s = float(t_s)
                self._cond.notify_all()
            after_s = self._now_s
            listeners = list(self._listeners)
        if after_s > before_s:
            for listener in listeners:
                listener(before_s, after_s, reading)
        return after_s

    def sleep(self, dt_s: float) -> None:
        if dt_s > 0:
            self._advance_by(float(dt_s), reading=False)

    def elapse_reading(self, dt_s: float) -> None:
        """Advance by ``dt_s`` while a stream is read: its frames of the span are produced."""
        if dt_s > 0:
            self._advance_by(float(dt_s), reading=True)

    def _advance_by(self, dt_s: float, reading: bool) -> None:
        with self._cond:
            before_s = self._now_s
            self._now_s = before_s + dt_s
            after_s = self._now_s
            self._cond.notify_all()
            listeners = list(self._listeners)
        for listener in listeners:
            listener(before_s, after_s, reading)

    def transport_wait(self, dt_s: float) -> None:
        """Return at once: nothing is in flight on simulated time.

        Only simulated ports live on a SimClock (``gyrocal run`` refuses a changed
        clock on real instruments), and they send bytes only in the controller's
        own advances; a simulated gyro drops what it made before a reader's
        flush at the controller's next advance, before it makes any new frame
        (``SimulatedGyroPort._honour_reader_flush``). So after its flush a reader
        gets exactly the frames of its next read, as after a long enough wait on a
        real port, and deterministically (a wall-time wait would race the writer).
        """

    def restore_s(self, t_s: float) -> None:
        """Set the time to ``t_s``, earlier or later, telling no listener.

        Only for restoring a simulated station's snapshot (a resumed dry run
        continues at the simulated time its interrupted session had reached,
        not at the time its own preflight and re-soak brought it to); the
        simulators are restored with it, so none of them sees time run back.
        """
        with self._cond:
            self._now_s = float(t_s)
            self._cond.notify_all()

    def wait_until(self, t_s: float, timeout_s: float | None = None) -> bool:
        """Block (in wall time) until someone advances the clock to ``t_s``.

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
