"""Gyro output ↔ input-referred rate in deg/h: the one conversion every analysis uses.

A gyro's output is ``scale_factor × rate`` in its output units
(gyro-model.md); every analysis judges rates in deg/h, input-referred. The
conversion was written inline in five places; here it is once, with the
output units it understands.
"""

from __future__ import annotations

import math

import numpy as np

#: deg/h per unit of each rate unit an output may be expressed in.
DPH_PER_UNIT = {"deg/s": 3600.0, "deg/h": 1.0, "rad/s": math.degrees(1.0) * 3600.0}


def output_to_dph(output, scale_factor: float, units: str = "deg/s") -> np.ndarray:
    """Input-referred rate (deg/h) of gyro output in ``units`` × ``scale_factor``."""
    return np.asarray(output, dtype=float) / scale_factor * DPH_PER_UNIT[units]


def dph_to_output(rate_dph, scale_factor: float, units: str = "deg/s") -> np.ndarray:
    """The output that an input-referred rate (deg/h) produces."""
    return np.asarray(rate_dph, dtype=float) * scale_factor / DPH_PER_UNIT[units]
