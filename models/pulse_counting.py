"""The `quantization` output stage: the indicated angle counted in whole pulses.

A ring-laser gyro (and any pulse-output gyro) does not report a rate: it
counts fringe pulses of q = ``pulse_arcsec``. Per readout the count is the
floor or the ceiling of the true angle advance, so the count error is 0 or 1
pulse, its variance for a steady rate is f(1−f) with f the fractional
advance per readout, and, because the residual phase is carried, the error
never accumulates (Golyaev & Kolbas 1991, seeds/001).

The spec's formula, per sample k:
output_k = sf·(⌊Θ_k/q⌋ − ⌊Θ_{k−1}/q⌋)·q·fs, Θ_k = Σ ω_ind/fs.
The accumulator is held as a phase in pulses in [0, 1) so it keeps full
precision over arbitrarily long runs and joins blocks without a seam.
"""

from __future__ import annotations

import math

import numpy as np


def count_pulses(
    advance_pulses: np.ndarray, phase_prev_pulses: float = 0.0
) -> tuple[np.ndarray, float]:
    """Whole pulses counted per readout for the given angle advances (in pulses).

    ``phase_prev_pulses`` is the fractional accumulated angle before the first
    readout (Θ_{−1}/q − ⌊Θ_{−1}/q⌋). Returns the integer counts (as float) and
    the fractional phase after the last readout.
    """
    advance = np.asarray(advance_pulses, dtype=float)
    if advance.size == 0:
        return advance.copy(), phase_prev_pulses
    theta = phase_prev_pulses + np.cumsum(advance)
    whole = np.floor(theta)
    counts = np.diff(whole, prepend=0.0)  # ⌊phase_prev⌋ = 0 since it is in [0, 1)
    end = float(theta[-1] - whole[-1])
    return counts, end


class PulseCounter:
    """Stateful pulse counter: rate in, quantized rate out (both deg/s, input-referred)."""

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("phase_pulses",)

    def __init__(self, pulse_arcsec: float, phase_pulses: float = 0.0) -> None:
        if not pulse_arcsec > 0:
            raise ValueError(f"quantization pulse must be > 0 arcsec, got {pulse_arcsec!r}")
        if not 0.0 <= phase_pulses < 1.0:
            raise ValueError(f"initial pulse phase must be in [0, 1), got {phase_pulses!r}")
        self.pulse_deg = pulse_arcsec / 3600.0
        self.phase_pulses = phase_pulses

    def quantize(self, rate_dps: np.ndarray, dt_s: np.ndarray | float) -> np.ndarray:
        """The rate each readout reports: counted pulses × q / dt."""
        rate = np.asarray(rate_dps, dtype=float)
        dt = np.broadcast_to(np.asarray(dt_s, dtype=float), rate.shape)
        counts, self.phase_pulses = count_pulses(rate * dt / self.pulse_deg, self.phase_pulses)
        if not math.isfinite(self.phase_pulses):
            raise ValueError("pulse counter received a non-finite rate")
        return counts * self.pulse_deg / dt
