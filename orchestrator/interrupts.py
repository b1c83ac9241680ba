"""Ctrl-C and SIGTERM, taken only at checkpoints: never inside an exchange or a journal line.

A signal is turned into ``KeyboardInterrupt`` so that the engine's one
``except`` path takes the run to the safe state. Where it is raised matters:

- inside a journal append, between the line's write and the writer's update
  of its chain hash, it would make the next line chain to the wrong hash;
- inside an instrument exchange, between a Modbus request and its reply, it
  would leave the reply in the socket, to be read later as the answer to the
  next request — the safe-setpoint write (issue 9: 5 of 19 interrupted runs
  said "instruments safe" on such a stale reply).

So both are *held*: a signal that arrives inside one is noted and raised when
it returns, at a checkpoint between exchanges. While the safe state itself is
being made the gate is *shielded*: a second Ctrl-C is acknowledged on stderr
and dropped, because stopping the safing half-way is never what the operator
wants.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Generic, TypeVar

from gyrocal.instruments.interfaces import (
    Chamber,
    ChamberStatus,
    HoldingTable,
    Identity,
    PositionTable,
    RateTable,
    SynthesisTable,
    TableStatus,
)

InstrumentT = TypeVar("InstrumentT", Chamber, RateTable)

SHIELD_NOTICE = (b"gyrocal: interrupt received while making the instruments safe; "
                 b"it waits until the safe state is done\n")
CLOSING_NOTICE = (b"gyrocal: interrupt received after the last step was recorded; the run is "
                  b"closed first (a moment), then gyrocal exits\n")


class InterruptGate:
    """SIGINT/SIGTERM become ``KeyboardInterrupt`` at checkpoints only (see the module text)."""

    def __init__(self) -> None:
        self._depth = 0
        self._pending: int | None = None
        self._shielded = False
        self._notice = SHIELD_NOTICE
        self.deferred: list[int] = []    # signals that arrived while shielded

    def _handler(self, signum: int, frame: object) -> None:
        if self._shielded:
            self.deferred.append(signum)
            os.write(2, self._notice)    # async-signal-safe, unlike print() into a busy stream
            return
        if self._depth:
            self._pending = signum
            return
        raise KeyboardInterrupt(f"signal {signum}")

    @contextmanager
    def held(self) -> Iterator[None]:
        """Inside: a signal is noted; it is raised as soon as the outermost ``held`` returns."""
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            if not self._depth and self._pending is not None and not self._shielded:
                signum, self._pending = self._pending, None
                raise KeyboardInterrupt(f"signal {signum}")

    @contextmanager
    def shielded(self) -> Iterator[None]:
        """While the safe state is made: further signals are acknowledged and never raised."""
        self._shielded = True
        self._pending = None
        try:
            yield
        finally:
            self._shielded = False
            self._pending = None

    def shield_for_good(self) -> None:
        """From here on nothing is left to interrupt (the run is being closed): a signal is
        acknowledged and kept in ``deferred``; the caller exits with the signal's code after."""
        self._shielded = True
        self._pending = None
        self._notice = CLOSING_NOTICE

    @contextmanager
    def installed(self, journal: Any) -> Iterator[None]:
        """Handle SIGINT/SIGTERM and hold them during ``journal.append`` (main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        append = journal.append

        def held_append(name: str, /, **fields: Any) -> dict[str, Any]:
            with self.held():
                return append(name, **fields)

        journal.append = held_append   # the commands' retry hook appends to this same journal
        previous = {sig: signal.signal(sig, self._handler) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            del journal.append


class ClosingSignals:
    """SIGINT/SIGTERM while a controller closes its run: raised at once until :meth:`arm`, then
    acknowledged and kept, so the few journal lines that close a run are never cut off.

    The engine's gate handles signals while it runs; this one holds the handlers
    around it, so the instant between the engine's return and the closing line
    has an owner too (a signal there used to end in a traceback or in -15).
    """

    def __init__(self) -> None:
        self.armed = False
        self.received: list[int] = []

    def _handler(self, signum: int, frame: object) -> None:
        if not self.armed:
            raise KeyboardInterrupt(f"signal {signum}")
        self.received.append(signum)
        os.write(2, CLOSING_NOTICE)

    def arm(self) -> None:
        self.armed = True

    @contextmanager
    def installed(self) -> Iterator[ClosingSignals]:
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = {sig: signal.signal(sig, self._handler) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield self
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


class _Gated(Generic[InstrumentT]):
    """The calls every instrument has, each one exchange a signal cannot cut in half."""

    def __init__(self, inner: InstrumentT, gate: InterruptGate) -> None:
        self.inner = inner
        self._gate = gate

    def identify(self) -> Identity:
        with self._gate.held():
            return self.inner.identify()

    def reset_link(self) -> None:
        with self._gate.held():
            self.inner.reset_link()

    def close(self) -> None:
        with self._gate.held():
            self.inner.close()


class GatedChamber(_Gated[Chamber]):
    """A chamber each of whose calls is one exchange a signal cannot cut in half."""

    def read_temperature_c(self) -> float:
        with self._gate.held():
            return self.inner.read_temperature_c()

    def read_setpoint_c(self) -> float:
        with self._gate.held():
            return self.inner.read_setpoint_c()

    def set_setpoint_c(self, setpoint_c: float) -> None:
        with self._gate.held():
            self.inner.set_setpoint_c(setpoint_c)

    def read_status(self) -> ChamberStatus:
        with self._gate.held():
            return self.inner.read_status()


class GatedTable(_Gated[RateTable]):
    """A rate table each of whose calls is one exchange a signal cannot cut in half."""

    def interlock_closed(self) -> bool:
        with self._gate.held():
            return self.inner.interlock_closed()

    def close_interlock(self) -> None:
        with self._gate.held():
            self.inner.close_interlock()

    def open_interlock(self) -> None:
        with self._gate.held():
            self.inner.open_interlock()

    def set_rate_mode(self) -> None:
        with self._gate.held():
            self.inner.set_rate_mode()

    def set_acceleration_limit_dps2(self, accel_dps2: float) -> None:
        with self._gate.held():
            self.inner.set_acceleration_limit_dps2(accel_dps2)

    def set_rate_dps(self, rate_dps: float) -> None:
        with self._gate.held():
            self.inner.set_rate_dps(rate_dps)

    def read_rate_dps(self) -> float:
        with self._gate.held():
            return self.inner.read_rate_dps()

    def read_position_deg(self) -> float:
        with self._gate.held():
            return self.inner.read_position_deg()

    @property
    def serves_position(self) -> bool:
        return isinstance(self.inner, PositionTable)

    def set_position_mode(self) -> None:
        inner = self.inner
        if not isinstance(inner, PositionTable):
            raise TypeError(f"table driver {type(inner).__name__} has no position mode")
        with self._gate.held():
            inner.set_position_mode()

    def set_position_deg(self, position_deg: float) -> None:
        inner = self.inner
        if not isinstance(inner, PositionTable):
            raise TypeError(f"table driver {type(inner).__name__} has no position mode")
        with self._gate.held():
            inner.set_position_deg(position_deg)

    def read_status(self) -> TableStatus:
        with self._gate.held():
            return self.inner.read_status()

    def hold(self) -> None:
        with self._gate.held():
            self._holding_table().hold()

    def read_servo_mode(self) -> str:
        with self._gate.held():
            return self._holding_table().read_servo_mode()

    def _holding_table(self) -> HoldingTable:
        inner = self.inner
        if not isinstance(inner, HoldingTable):
            raise TypeError(f"table driver {type(inner).__name__} cannot hold its axis under servo")
        return inner

    def stop(self) -> None:
        with self._gate.held():
            self.inner.stop()

    def set_oscillator(self, magnitude: float, frequency_hz: float, phase_deg: float) -> None:
        with self._gate.held():
            self._synthesis_table().set_oscillator(magnitude, frequency_hz, phase_deg)

    def set_synthesis_mode(self) -> None:
        with self._gate.held():
            self._synthesis_table().set_synthesis_mode()

    def _synthesis_table(self) -> SynthesisTable:
        if not isinstance(self.inner, SynthesisTable):
            raise TypeError(f"{type(self.inner).__name__} has no synthesis mode")
        return self.inner
