"""Simulated Keysight 34465A reading an analog gyro: a SCPI server whose readings are the gyro model's volts.

Between ``INIT`` and ``ABORt`` the sample timer runs: reading k is the model's
output at ``t_init + k / fs`` (the shared physics: table rate, chamber air
temperature), held in a reading memory that ``DATA:REMove?`` empties. On
simulated time, asking ``DATA:POINts?`` with the memory empty lets the timer
run one block (the clock advances), as the simulated STIM300 does when read.

A one-shot ``MEAS:VOLT:DC?`` (or ``READ?``) answers the model's volts now, as
a meter used by a simple script would.

Someone else's driver (QCoDeS's Keysight 34465A, tests/instruments/gyro/
test_truevolt_qcodes_peer.py) reads the meter as well, so the simulator also
keeps what that driver asks of a real one: every setting is read back in the
meter's own form (``SAMPle:COUNt?`` → ``+1``), ``SENSe:VOLTage:NPLC`` and the
other settings work without the optional ``SENSe`` and ``DC`` nodes, NPLC and
aperture switch each other's mode, the resolution follows range and NPLC,
``SAMPle:TIMer? MIN`` is the integration time (twice it with auto-zero on), a
``TRIGger:SOURce BUS`` run waits after ``INIT`` for ``*TRG``, and ``FETCH?``
waits for the run to end and answers every reading without removing any.
All are unconfirmed against the programming guide (docs/protocol-elements.md).

Faults: ``overload`` (readings are 9.9E37: count = readings), ``stall`` (the
timer stops), ``no_reply``, ``drop_connection``.
"""

from __future__ import annotations

import math
import time
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


#: NPLC settings of a 34465A with the DIG option and the resolution each gives, as a fraction
#: of the range (the table of QCoDeS's Keysight344xxA driver; unconfirmed)
_NPLC_RESOLUTION = ((0.001, 30e-6), (0.002, 15e-6), (0.006, 6e-6), (0.02, 3e-6), (0.06, 1.5e-6),
                    (0.2, 0.7e-6), (1.0, 0.3e-6), (10.0, 0.1e-6), (100.0, 0.03e-6))
#: settings at power-on (keys in short form without the optional SENSe node), values as read back
_DEFAULTS = {"FUNC": '"VOLT"', "VOLT:DC:RANG": "10", "VOLT:DC:RANG:AUTO": "0",
             "VOLT:DC:NPLC": "10", "VOLT:DC:APER": "0.1", "VOLT:DC:APER:ENAB": "0",
             "VOLT:DC:ZERO:AUTO": "1", "TRIG:SOUR": "IMM", "TRIG:COUN": "1", "TRIG:DEL": "0",
             "TRIG:DEL:AUTO": "1", "TRIG:SLOP": "POS", "SAMP:SOUR": "IMM", "SAMP:TIM": "0.001",
             "SAMP:COUN": "1", "SAMP:COUN:PRET": "0", "DISP:STAT": "1", "DISP:TEXT": '""',
             "SYST:LFR": "50"}
_INTEGER = ("SAMP:COUN", "SAMP:COUN:PRET", "VOLT:DC:RANG:AUTO", "VOLT:DC:APER:ENAB",
            "VOLT:DC:ZERO:AUTO", "TRIG:DEL:AUTO", "DISP:STAT", "SYST:LFR")
_WORDS = ("FUNC", "TRIG:SOUR", "TRIG:SLOP", "SAMP:SOUR", "DISP:TEXT")


class SimulatedTruevolt(SimulatedScpiInstrument):
    #: what a resumed dry run restores (models/sim_state.py): the settings, the reading
    #: memory and the sample timer
    SIM_STATE = ("settings", "_memory", "_k_next", "_t_init", "_waiting_for_trigger")

    def __init__(self, source: Callable, clock: Clock, faults: FaultInjector | None = None) -> None:
        super().__init__(faults or FaultInjector(FAULTS, owner="simulated DMM"), IDN)
        self.source, self.clock = source, clock
        self.settings: dict[str, str] = dict(_DEFAULTS)
        self._memory: deque[float] = deque()
        self._k_next = 0
        self._t_init: float | None = None
        self._waiting_for_trigger = False

    @property
    def fs_hz(self) -> float:
        return 1.0 / float(self.settings["SAMP:TIM"])

    @property
    def range_v(self) -> float:
        return float(self.settings["VOLT:DC:RANG"])

    def answer(self, line: str) -> str | None:
        head, _, arg = line.partition(" ")
        key, arg = _canonical(head), arg.strip()
        if key == "INIT":
            self._memory.clear()
            self._k_next, self._t_init = 0, None
            self._waiting_for_trigger = self.settings["TRIG:SOUR"] == "BUS"
            if not self._waiting_for_trigger:
                self._start_timer()
            return None
        if key == "*TRG":
            if self._waiting_for_trigger:
                self._waiting_for_trigger = False
                self._start_timer()
            return None
        if key == "ABOR":
            self._t_init, self._waiting_for_trigger = None, False
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
        if key == "FETC?":
            return self._fetch()
        if key in ("MEAS:VOLT:DC?", "MEAS:VOLT?", "READ?"):     # one reading, now
            volts, _ = self.source(np.array([self.clock.now_s()]))
            value = float(np.asarray(volts, dtype=np.float64).ravel()[0])
            return f"{value if abs(value) <= 1.2 * self.range_v else OVERLOAD:+.9E}"
        if key == "CAL:DATE?":
            return CALIBRATION_DATE
        if key == "*OPT?":
            return "0"          # no licensed option listed (DIG is in the A.03 firmware)
        if key == "DISP:TEXT:CLE":
            self.settings["DISP:TEXT"] = '""'
            return None
        if key.endswith("?"):
            return self._query(key[:-1], arg)
        return self._set(key, arg)

    def _query(self, key: str, arg: str) -> str:
        if key == "VOLT:DC:RES":
            return f"{self.range_v * _resolution_fraction(self._nplc()):+.8E}"
        if key == "SAMP:TIM" and arg.upper().startswith("MIN"):
            zero = 2.0 if self.settings["VOLT:DC:ZERO:AUTO"] == "1" else 1.0
            return f"{zero * self._integration_s():+.8E}"
        if key not in self.settings:
            raise ScpiError(-113, "Undefined header")
        value = self.settings[key]
        if key in _WORDS:
            return value
        if key in _INTEGER:
            return f"{int(float(value)):+d}"
        return f"{float(value):+.8E}"

    def _set(self, key: str, arg: str) -> None:
        if key not in self.settings or key == "SYST:LFR":
            raise ScpiError(-113, "Undefined header")
        if key in _WORDS and key != "DISP:TEXT":
            arg = _SHORT.get(arg.upper(), arg.upper())
        elif key not in _WORDS:
            # DEF is the power-on value; MIN and MAX are not modelled (refused, never guessed)
            arg = {"ON": "1", "OFF": "0", "DEF": _DEFAULTS[key]}.get(arg.upper(), arg)
            try:
                float(arg)
            except ValueError:
                raise ScpiError(-224, "Illegal parameter value") from None
        self.settings[key] = arg
        if key == "VOLT:DC:APER":          # aperture and NPLC each switch the other off
            self.settings["VOLT:DC:APER:ENAB"] = "1"
        elif key == "VOLT:DC:NPLC":
            self.settings["VOLT:DC:APER:ENAB"] = "0"
        return None

    def _nplc(self) -> float:
        if self.settings["VOLT:DC:APER:ENAB"] == "1":
            return float(self.settings["VOLT:DC:APER"]) * float(self.settings["SYST:LFR"])
        return float(self.settings["VOLT:DC:NPLC"])

    def _integration_s(self) -> float:
        return self._nplc() / float(self.settings["SYST:LFR"])

    def _start_timer(self) -> None:
        # the timer starts on the next whole sample period of the clock
        self._t_init = math.ceil(self.clock.now_s() * self.fs_hz) / self.fs_hz

    def _fetch(self) -> str:
        """Wait for the run to end (on sim time: let it pass), then every reading, none removed."""
        if self._t_init is None:
            raise ScpiError(-230, "Data corrupt or stale")
        count = int(float(self.settings["SAMP:COUN"])) * int(float(self.settings["TRIG:COUN"]))
        t_end = self._t_init + count / self.fs_hz
        if isinstance(self.clock, SimClock):
            self.clock.advance_to(max(t_end, self.clock.now_s()))
        else:
            time.sleep(max(0.0, t_end - self.clock.now_s()))
        self._take(count)
        return ",".join(f"{v:+.9E}" for v in self._memory)

    def _run_timer(self) -> None:
        """Put into memory every reading the timer has taken by now (on sim time: one more block)."""
        if self._t_init is None or self.faults.is_armed("stall"):
            return
        fs = self.fs_hz
        if isinstance(self.clock, SimClock):
            if self._memory:
                return
            k_end = self._k_next + _BLOCK
            self.clock.advance_to(self._t_init + k_end / fs)
        else:
            k_end = math.floor((self.clock.now_s() - self._t_init) * fs) + 1
        self._take(k_end)

    def _take(self, k_end: int) -> None:
        """Readings ``k_next … k_end - 1`` of the run (no more than the sample count) into memory."""
        assert self._t_init is not None
        k_end = min(k_end, int(float(self.settings["SAMP:COUN"])))
        if k_end <= self._k_next:
            return
        k = np.arange(self._k_next, k_end)
        volts, _ = self.source(self._t_init + k / self.fs_hz)
        volts = np.asarray(volts, dtype=np.float64).reshape(len(k), -1)[:, 0]
        volts = np.where(np.abs(volts) > 1.2 * self.range_v, OVERLOAD, volts)
        if self.faults.take("overload") is not None:
            volts = np.full_like(volts, OVERLOAD)
        self._memory.extend(volts.tolist())
        self._k_next = k_end


def _resolution_fraction(nplc: float) -> float:
    """The resolution (fraction of range) of the longest listed NPLC not above ``nplc``."""
    fraction = _NPLC_RESOLUTION[0][1]
    for listed, value in _NPLC_RESOLUTION:
        if listed <= nplc * (1 + 1e-9):
            fraction = value
    return fraction


_SHORT = {"SENSE": "SENS", "FUNCTION": "FUNC", "VOLTAGE": "VOLT", "RANGE": "RANG",
          "APERTURE": "APER", "TRIGGER": "TRIG", "SOURCE": "SOUR", "COUNT": "COUN",
          "SAMPLE": "SAMP", "TIMER": "TIM", "POINTS": "POIN", "REMOVE": "REM",
          "CALIBRATION": "CAL", "ABORT": "ABOR", "INITIATE": "INIT", "IMMEDIATE": "IMM",
          "EXTERNAL": "EXT", "INTERNAL": "INT", "FETCH": "FETC", "DISPLAY": "DISP",
          "STATE": "STAT", "CLEAR": "CLE", "ENABLED": "ENAB", "ENABLE": "ENAB",
          "RESOLUTION": "RES", "PRETRIGGER": "PRET", "DELAY": "DEL", "SLOPE": "SLOP",
          "SYSTEM": "SYST", "LFREQUENCY": "LFR", "MEASURE": "MEAS", "POSITIVE": "POS",
          "NEGATIVE": "NEG"}


def _short(header: str) -> str:
    """``SENSe:VOLTage:DC:RANGe`` → ``SENS:VOLT:DC:RANG`` (SCPI long and short forms alike)."""
    query = header.endswith("?")
    parts = [_SHORT.get(p.upper(), p.upper()) for p in header.lstrip(":").rstrip("?").split(":")]
    return ":".join(parts) + ("?" if query else "")


def _canonical(header: str) -> str:
    """Short form without the optional nodes: ``SENSe:VOLT:NPLC`` → ``VOLT:DC:NPLC``,
    ``SENSe:FUNCtion`` → ``FUNC`` (SENSe is the default subsystem, DC the default of VOLTage)."""
    key = _short(header)
    if key.startswith("SENS:"):
        key = key[len("SENS:"):]
    if key.startswith("VOLT:") and not key.startswith(("VOLT:DC", "VOLT:AC")):
        key = "VOLT:DC:" + key[len("VOLT:"):]
    return key
