"""Simulated Keysight 34465A reading an analog gyro: a SCPI server whose readings are the gyro model's volts.

Between ``INIT`` and ``ABORt`` the sample timer runs: reading k is the model's
output at ``t_init + k / fs`` (the shared physics: table rate, chamber air
temperature), held in a reading memory that ``DATA:REMove?`` empties. On
simulated time, asking ``DATA:POINts?`` with the memory empty lets the timer
run one block (the clock advances), as the simulated STIM300 does when read.

A one-shot ``MEAS:VOLT:DC?`` (or ``READ?``) answers the model's volts now, as
a meter used by a simple script would.

Faults: ``overload`` (readings are 9.9E37: count = readings), ``stall`` (the
timer stops), ``no_reply``, ``drop_connection``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.scpi_server import COMMON_FAULTS, ScpiError, SimulatedScpiInstrument
from gyrocal.models.clock import Clock, SimClock

FAULTS = (*COMMON_FAULTS, "overload", "stall")
IDN = "Keysight Technologies,34465A,MY00000002,A.03.01-03.15-03.01-00.52-04-02"
CALIBRATION_DATE = "2026,03,17"
OVERLOAD = 9.9e37
_BLOCK = 256


class SimulatedTruevolt(SimulatedScpiInstrument):
    def __init__(self, source: Callable, clock: Clock, faults: FaultInjector | None = None) -> None:
        super().__init__(faults or FaultInjector(FAULTS, owner="simulated DMM"), IDN)
        self.source, self.clock = source, clock
        self.settings: dict[str, str] = {"RANG": "10", "SAMP:TIM": "0.001", "SAMP:COUN": "1"}
        self._memory: deque[float] = deque()
        self._k_next = 0
        self._t_init: float | None = None

    @property
    def fs_hz(self) -> float:
        return 1.0 / float(self.settings["SAMP:TIM"])

    def answer(self, line: str) -> str | None:
        head, _, arg = line.partition(" ")
        key = _short(head)
        if key == "INIT":
            self._memory.clear()
            self._k_next = 0
            # the timer starts on the next whole sample period of the clock
            self._t_init = math.ceil(self.clock.now_s() * self.fs_hz) / self.fs_hz
            return None
        if key == "ABOR":
            self._t_init = None
            return None
        if key == "DATA:POIN?":
            self._run_timer()
            return str(len(self._memory))
        if key == "DATA:REM?":
            count = int(arg.split(",")[0])
            if count > len(self._memory):
                raise ScpiError(-222, "Data out of range")
            values = [self._memory.popleft() for _ in range(count)]
            return ",".join(f"{v:+.9E}" for v in values)
        if key in ("MEAS:VOLT:DC?", "MEAS:VOLT?", "READ?"):     # one reading, now
            volts, _ = self.source(np.array([self.clock.now_s()]))
            value = float(np.asarray(volts, dtype=np.float64).ravel()[0])
            return f"{value if abs(value) <= 1.2 * float(self.settings['RANG']) else OVERLOAD:+.9E}"
        if key == "CAL:DATE?":
            return CALIBRATION_DATE
        if key.endswith("?"):
            return self.settings.get(key[:-1], "0")
        if key in ("SENS:FUNC", "SENS:VOLT:DC:RANG", "SENS:VOLT:DC:ZERO:AUTO", "SENS:VOLT:DC:APER",
                   "SENS:VOLT:DC:NPLC", "TRIG:SOUR", "TRIG:COUN", "SAMP:SOUR", "SAMP:TIM",
                   "SAMP:COUN"):
            self.settings[key.replace("SENS:VOLT:DC:", "")] = arg.strip()
            return None
        raise ScpiError(-113, "Undefined header")

    def _run_timer(self) -> None:
        """Put into memory every reading the timer has taken by now (on sim time: one more block)."""
        if self._t_init is None or self.faults.is_armed("stall"):
            return
        fs = self.fs_hz
        limit = int(float(self.settings["SAMP:COUN"]))
        if isinstance(self.clock, SimClock):
            if self._memory:
                return
            k_end = self._k_next + _BLOCK
            self.clock.advance_to(self._t_init + k_end / fs)
        else:
            k_end = math.floor((self.clock.now_s() - self._t_init) * fs) + 1
        k_end = min(k_end, limit)
        if k_end <= self._k_next:
            return
        k = np.arange(self._k_next, k_end)
        volts, _ = self.source(self._t_init + k / fs)
        volts = np.asarray(volts, dtype=np.float64).reshape(len(k), -1)[:, 0]
        range_v = float(self.settings["RANG"])
        volts = np.where(np.abs(volts) > 1.2 * range_v, OVERLOAD, volts)
        if self.faults.take("overload") is not None:
            volts = np.full_like(volts, OVERLOAD)
        self._memory.extend(volts.tolist())
        self._k_next = k_end


_SHORT = {"SENSE": "SENS", "FUNCTION": "FUNC", "VOLTAGE": "VOLT", "RANGE": "RANG",
          "APERTURE": "APER", "TRIGGER": "TRIG", "SOURCE": "SOUR", "COUNT": "COUN",
          "SAMPLE": "SAMP", "TIMER": "TIM", "POINTS": "POIN", "REMOVE": "REM",
          "CALIBRATION": "CAL", "ABORT": "ABOR", "INITIATE": "INIT"}


def _short(header: str) -> str:
    """``SENSe:VOLTage:DC:RANGe`` → ``SENS:VOLT:DC:RANG`` (SCPI long and short forms alike)."""
    query = header.endswith("?")
    parts = [_SHORT.get(p.upper(), p.upper()) for p in header.rstrip("?").split(":")]
    return ":".join(parts) + ("?" if query else "")
