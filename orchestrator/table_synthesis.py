"""The table's sinusoid for a frequency-response step: what was commanded, and when.

A frequency-response step (IEEE Std 952 / 1431) measures the gyro's output against the
rate the table turned. The ACUTROL's synthesis mode (TM-8004 §4.3.4, §4.7.6) takes the
sinusoid as a peak *position* displacement, frequency and initial phase; the step gives a
peak *rate*, so the displacement is rate / (2πf). With initial phase 0 the position is
A·sin(2πf(t − t₀)) and the rate 2πfA·cos(2πf(t − t₀)), t₀ the clock time the mode was
entered: that rate, at each sample's time, is the reference the step logs (its readback
is polled once per block, far too seldom to trace a sinusoid, and is kept as the check
against it).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.interfaces import RateTable, SynthesisTable
from gyrocal.orchestrator.interrupts import GatedTable
from gyrocal.orchestrator.run_errors import RunFaultError

#: The table is held at rest this long before synthesis mode: the at-rate band lets the
#: last fraction of a deceleration pass as "at rest", and the sinusoid starts from rest.
REST_BEFORE_SYNTHESIS_S = 1.0


@dataclass(frozen=True)
class Sinusoid:
    """Rate ``amplitude_dps``·cos(2π ``freq_hz`` (t − ``start_s``)), t on the run's clock."""

    amplitude_dps: float
    freq_hz: float
    start_s: float

    @property
    def displacement_deg(self) -> float:
        """Peak position displacement, what :Demand:Oscillator takes (TM-8004 §4.3.4)."""
        return self.amplitude_dps / (2.0 * math.pi * self.freq_hz)

    def rate_dps(self, t_s: np.ndarray | float) -> np.ndarray:
        return self.amplitude_dps * np.cos(2.0 * math.pi * self.freq_hz
                                           * (np.asarray(t_s, dtype=float) - self.start_s))


def start_sinusoid(table: RateTable | GatedTable, now_s: Callable[[], float],
                   amplitude_dps: float, freq_hz: float) -> Sinusoid:
    """Load the oscillator and enter synthesis mode from rest; the sinusoid starts when the
    mode command has been answered (``now_s()`` then: the controller acts on receipt, so
    the command's reply time is the uncertainty of the start)."""
    inner = table.inner if isinstance(table, GatedTable) else table
    if not isinstance(inner, SynthesisTable):
        raise RunFaultError("table: the station's table driver has no synthesis mode; a "
                            "frequency_response step cannot run on it")
    target = table if isinstance(table, GatedTable) else inner
    target.set_oscillator(amplitude_dps / (2.0 * math.pi * freq_hz), freq_hz, 0.0)
    target.set_synthesis_mode()
    return Sinusoid(amplitude_dps, freq_hz, now_s())
