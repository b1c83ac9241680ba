"""A pulse-output gyro (ring laser) read through a Keysight 53220A/53230A universal counter.

The counter totalizes the gyro's pulse channel over back-to-back gates of one
readout each (gate = 1 / fs), the readings queued in its memory; the driver
pulls them as they come. Each reading is a whole number of pulses, turned into
an angle increment by the pulse weight (arcsec per pulse) and reported as the
readout's mean rate, deg/s: the one-pulse discreteness of the count (Golyaev &
Kolbas: 0 or 1 pulse per readout, RMS ≈ 0.41 pulse over rates) stays in the data.
The gate number since ``INIT`` is the sample's time.

Commands (SCPI, LF): ``CONFigure:TOTalize:TIMed g,(@ch)``, ``TRIGger:SOURce IMMediate``,
``TRIGger:COUNt 1``, ``SAMPle:COUNt n``, ``INIT``, ``ABORt``, ``DATA:POINts?``,
``DATA:REMove? n``. The 53220A/53230A programming guide was not available: all
**unconfirmed** in docs/protocol-elements.md, including whether timed gates follow
each other without dead time (the simulator assumes they do).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.gyro.reading_memory import ReadingMemoryGyro
from gyrocal.instruments.interfaces import GyroBlock, Identity
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.scpi_link import ScpiLink

DRIVER_NAME = "keysight_53230a"
SAMPLE_COUNT = 1_000_000


def totalize_setup(channel: int, fs_hz: float) -> list[str]:
    """The lines that start back-to-back timed totalize gates of one readout each."""
    return ["ABORt", f"CONFigure:TOTalize:TIMed {1.0 / fs_hz:.9g},(@{channel})",
            "TRIGger:SOURce IMMediate", "TRIGger:COUNt 1", f"SAMPle:COUNt {SAMPLE_COUNT}", "INIT"]


def _whole_counts(values: list[float], count: int) -> str | None:
    """Each totalize reading is a whole number of pulses, one per readout asked."""
    if len(values) != count or any(v != round(v) for v in values):
        return f"expected {count} whole counts"
    return None


class CounterPulseGyro(ReadingMemoryGyro):
    """``GyroStream`` for a pulse gyro on a universal counter: counts × pulse weight → deg/s."""

    def __init__(self, resource: str, sample_rate_hz: float, pulse_weight_arcsec: float,
                 channel: int = 1, timeout_s: float = 2.0, retry: RetryPolicy | None = None,
                 name: str = "gyro",
                 on_retry: Callable[[int, InstrumentError], None] | None = None) -> None:
        if not (sample_rate_hz > 0 and pulse_weight_arcsec > 0):
            raise ValueError(f"{name}: sample_rate_hz and pulse_weight_arcsec must be > 0")
        self.resource, self.name, self.fs_hz = resource, name, float(sample_rate_hz)
        self.pulse_deg = float(pulse_weight_arcsec) / 3600.0
        self.channel = int(channel)
        self.link = ScpiLink(resource, name, timeout_s, retry or RetryPolicy(), on_retry)
        super().__init__()

    def identify(self) -> Identity:
        return Identity("gyro", DRIVER_NAME, self.resource,
                        f"pulse input chain: timed totalize through {self.link.ask('*IDN?')}; "
                        f"channel {self.channel}, gate {1e3 / self.fs_hz:g} ms, pulse weight "
                        f"{self.pulse_deg * 3600:g} arcsec")

    def _setup_lines(self) -> list[str]:
        return totalize_setup(self.channel, self.fs_hz)

    def _check(self, values: list[float], count: int) -> str | None:
        return _whole_counts(values, count)

    def _block(self, values: np.ndarray, index: np.ndarray) -> GyroBlock:
        rate_dps = values * self.pulse_deg * self.fs_hz
        return GyroBlock(rate=rate_dps, counter=(index % 256).astype(np.uint8), index=index,
                         status=np.zeros(len(values), np.uint8), extra={"pulses": values})
