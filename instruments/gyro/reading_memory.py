"""Pulling readings out of a SCPI meter's reading memory (``DATA:POINts?``, ``DATA:REMove? n``).

The Truevolt DMM and the 53220A/53230A counter both queue timed readings in their
memory and hand them over the same way; one owner for the polling loop and the
reply parsing keeps their timeout and resynchronisation behaviour identical.
Each driver keeps its own check of what a reading may be (whole counts, finite volts).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.errors import InstrumentError, InstrumentTimeout
from gyrocal.instruments.interfaces import GyroBlock
from gyrocal.instruments.scpi_link import ScpiLink

#: a reply's problem given (readings, count asked), or None when they are acceptable
ReadingsCheck = Callable[[list[float], int], str | None]


def remove_readings(link: ScpiLink, name: str, count: int, check: ReadingsCheck) -> list[float]:
    """``DATA:REMove? count``: an unreadable reply resets the link (transient error)."""
    command = f"DATA:REMove? {count}"
    reply = link.ask(command)
    try:
        values = [float(v) for v in reply.split(",") if v.strip()]
    except ValueError:
        link.reset()
        raise InstrumentError(name, command, "unreadable readings", reply=reply[:80],
                              transient=True) from None
    problem = check(values, count)
    if problem is not None:
        raise InstrumentError(name, command, problem, reply=reply[:80])
    return values


def pull_readings(link: ScpiLink, name: str, n: int, timeout_s: float, fs_hz: float,
                  check: ReadingsCheck,
                  sleep: Callable[[float], None] = time.sleep) -> list[float]:
    """Wait for and remove ``n`` readings, polling ``DATA:POINts?`` at about a quarter of the
    time the missing readings take (1-50 ms) so a slow rate does not spin the link."""
    values: list[float] = []
    deadline = time.monotonic() + timeout_s
    while len(values) < n:
        points = int(link.ask_float("DATA:POINts?"))
        if points > 0:
            values += remove_readings(link, name, min(points, n - len(values)), check)
            continue
        if time.monotonic() > deadline:
            raise InstrumentTimeout(name, "DATA:POINts?",
                                    f"{len(values)} of {n} readings within {timeout_s:g} s")
        sleep(min(0.05, max(0.001, (n - len(values)) / fs_hz / 4)))
    return values


class ReadingMemoryGyro:
    """``GyroStream`` skeleton for a gyro read through a meter's reading memory.

    The sample number since ``INIT`` is the sample's time, so flush() restarts the
    meter's run and the numbering together; a subclass gives the setup lines, what
    a reading may be, and how readings become a :class:`GyroBlock`.
    """

    name: str
    fs_hz: float
    link: ScpiLink

    def __init__(self) -> None:
        self._sleep: Callable[[float], None] = time.sleep
        self._next_index = 0          # sample number (since INIT) of the next reading pulled
        self._started = False

    def _setup_lines(self) -> list[str]:
        raise NotImplementedError

    def _check(self, values: list[float], count: int) -> str | None:
        raise NotImplementedError

    def _block(self, values: np.ndarray, index: np.ndarray) -> GyroBlock:
        raise NotImplementedError

    def flush(self) -> None:
        """Restart the stream: the next reading is sample 0 of a fresh run."""
        for line in self._setup_lines():
            self.link.send(line)
        self._next_index = 0
        self._started = True

    def read_samples(self, n: int, timeout_s: float) -> GyroBlock:
        if not self._started:
            self.flush()
        values = np.asarray(pull_readings(self.link, self.name, n, timeout_s, self.fs_hz,
                                          self._check, self._sleep), dtype=np.float64)
        index = np.arange(self._next_index, self._next_index + len(values), dtype=np.int64)
        self._next_index += len(values)
        return self._block(values, index)

    def close(self) -> None:
        with contextlib.suppress(InstrumentError):
            self.link.send("ABORt")
        self.link.close()
