"""What a powered rate-table drive puts into a gyro at rest: lines and extra noise.

The vendor notes (seeds/003, "Magnetic Sensitivity of FOG IMU" §2.2) logged
an IMU on a turntable with the drive off and on: on, the drift rose 5–10×
and lines appeared at 12.48, 24.96 and 37.44 Hz (the drive's PWM/commutation
family coupling mechanically and magnetically). The simulator adds this
while the simulated table's interlock is closed (its drive powered), so
`gyrocal analyze interference` has something to find; the lines and the
extra white noise are a station's ``simulation.table`` setting, never part
of the gyro model (they belong to the table, not the unit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DriveLine:
    frequency_hz: float
    amplitude_dph: float          # 0-to-peak, deg/h at the gyro's input


class DriveInterference:
    """Input-referred interference (deg/h) at frame times, while the drive is powered."""

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_rng", "_phases")

    def __init__(self, lines: tuple[DriveLine, ...], noise_dph: float, fs_hz: float,
                 seed: int) -> None:
        self.lines = tuple(lines)
        self.noise_dph = float(noise_dph)     # extra white noise per sample, deg/h (1 σ)
        self.fs_hz = float(fs_hz)
        self._rng = np.random.default_rng(seed)
        self._phases = self._rng.uniform(0.0, 2 * np.pi, len(self.lines))

    @property
    def active(self) -> bool:
        return bool(self.lines) or self.noise_dph > 0

    def __call__(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        out = self._rng.standard_normal(t.shape) * self.noise_dph
        for line, phase in zip(self.lines, self._phases, strict=True):
            out += line.amplitude_dph * np.sin(2 * np.pi * line.frequency_hz * t + phase)
        return out
