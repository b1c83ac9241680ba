"""Pulling readings out of a SCPI meter's reading memory (``DATA:POINts?``, ``DATA:REMove? n``).

The Truevolt DMM and the 53220A/53230A counter both queue timed readings in their
memory and hand them over the same way; one owner for the polling loop and the
reply parsing keeps their timeout and resynchronisation behaviour identical.
Each driver keeps its own check of what a reading may be (whole counts, finite volts).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from gyrocal.instruments.errors import InstrumentError, InstrumentTimeout
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
