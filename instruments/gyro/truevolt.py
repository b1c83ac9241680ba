"""An analog gyro read through a Keysight Truevolt DMM (34465A/34470A; the 34461A as a subset).

The unit's output voltage is sampled by the meter's own sample timer, gap-free,
into its reading memory; the driver pulls readings as they come. The sample
number since ``INIT`` is the sample's time (index / fs), so timestamps come
from the meter's timer, not from when the host happened to read. An overload
reading (9.9E37, the meter's overflow value) is kept and flagged, counted as a
bad sample like a STIM300 status flag.

Commands (SCPI, LF): ``SENSe:FUNCtion "VOLT"``, ``SENSe:VOLTage:DC:RANGe r``,
``SENSe:VOLTage:DC:ZERO:AUTO OFF``, ``SENSe:VOLTage:DC:APERture s`` or
``SENSe:VOLTage:DC:NPLC n``, ``TRIGger:SOURce IMM``, ``TRIGger:COUNt 1``,
``SAMPle:SOURce TIMer``, ``SAMPle:TIMer s``, ``SAMPle:COUNt n``, ``INIT``, ``ABORt``
(spelled as QCoDeS's Keysight 344xxA driver spells them), ``DATA:POINts?``,
``DATA:REMove? n``, ``CALibration:DATE?``. The 34465A programming guide was not
available: all are **unconfirmed** in docs/protocol-elements.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.gyro.reading_memory import ReadingMemoryGyro
from gyrocal.instruments.interfaces import GyroBlock, Identity
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.scpi_link import ScpiLink

DRIVER_NAME = "keysight_34465a"
#: the meter's overload reading (a value at or beyond it is an overload, not a voltage)
OVERLOAD_V = 9.9e37
#: readings the meter is asked to take per INIT (the reading memory is 1e6 with no option)
SAMPLE_COUNT = 1_000_000
DC_RANGES_V = (0.1, 1.0, 10.0, 100.0, 1000.0)


def stream_setup(range_v: float, fs_hz: float, aperture_s: float | None,
                 nplc: float | None) -> list[str]:
    """The lines that start a timed, gap-free DC-volts stream (in order)."""
    integration = (f"SENSe:VOLTage:DC:NPLC {nplc:g}" if nplc is not None
                   else f"SENSe:VOLTage:DC:APERture {aperture_s:g}")
    return ["ABORt", 'SENSe:FUNCtion "VOLT"', f"SENSe:VOLTage:DC:RANGe {range_v:g}",
            "SENSe:VOLTage:DC:ZERO:AUTO OFF", integration, "TRIGger:SOURce IMM",
            "TRIGger:COUNt 1", "SAMPle:SOURce TIMer", f"SAMPle:TIMer {1.0 / fs_hz:.9g}",
            f"SAMPle:COUNt {SAMPLE_COUNT}", "INIT"]


def _finite_readings(values: list[float], count: int) -> str | None:
    """One finite reading per reading asked (an overload is finite: 9.9E37)."""
    if len(values) != count or not all(math.isfinite(v) for v in values):
        return f"{len(values)} readings, asked {count}"
    return None


class TruevoltAnalogGyro(ReadingMemoryGyro):
    """``GyroStream`` for an analog gyro on a Truevolt DMM (volts out, in the unit's output units)."""

    def __init__(self, resource: str, sample_rate_hz: float, range_v: float = 10.0,
                 aperture_s: float | None = None, nplc: float | None = None,
                 timeout_s: float = 2.0, retry: RetryPolicy | None = None, name: str = "gyro",
                 on_retry: Callable[[int, InstrumentError], None] | None = None,
                 clock_sleep: Callable[[float], None] = time.sleep) -> None:
        if not sample_rate_hz > 0:
            raise ValueError(f"{name}: sample_rate_hz must be > 0")
        self.resource, self.name, self.fs_hz = resource, name, float(sample_rate_hz)
        self.range_v = float(range_v)
        # Aperture: 80 % of the sample period unless the station gives one (or NPLC).
        self.aperture_s = aperture_s if aperture_s or nplc else 0.8 / self.fs_hz
        self.nplc = nplc
        self.timeout_s = float(timeout_s)
        self.link = ScpiLink(resource, name, timeout_s, retry or RetryPolicy(), on_retry)
        super().__init__()
        self._sleep = clock_sleep

    def identify(self) -> Identity:
        idn = self.link.ask("*IDN?")
        cal = self.link.ask("CALibration:DATE?").replace(",", "-").replace("+", "")
        integration = (f"NPLC {self.nplc:g}" if self.nplc is not None
                       else f"aperture {self.aperture_s * 1e3:g} ms")
        return Identity("gyro", DRIVER_NAME, self.resource,
                        f"analog input chain: DC volts through {idn}; last calibrated {cal}; "
                        f"range {self.range_v:g} V, {integration}, sample timer "
                        f"{self.fs_hz:g} Hz")

    def _setup_lines(self) -> list[str]:
        return stream_setup(self.range_v, self.fs_hz, self.aperture_s, self.nplc)

    def _check(self, values: list[float], count: int) -> str | None:
        return _finite_readings(values, count)

    def _block(self, values: np.ndarray, index: np.ndarray) -> GyroBlock:
        overload = np.abs(values) >= OVERLOAD_V
        return GyroBlock(rate=values, counter=(index % 256).astype(np.uint8), index=index,
                         status=overload.astype(np.uint8), flagged=overload)
