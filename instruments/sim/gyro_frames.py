"""What the simulated STIM300 puts in each datagram: the declared type, the datasheet's counter.

Kept apart from the pty writer (gyro_pty.py), which decides *when* frames
are written; this decides *which bytes* a frame is. The simulated unit
sits still and level: its accelerometers and inclinometers read the
specific force of gravity, +1 g on z (as the real unit of the UBC captures
does, TS1524 Figure 6-5 axes), every cluster's temperature is the
model's sensor temperature, and the counter advances 2000 / fs per datagram
(TS1524 §7.5.2.2.18).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro.channels import SensorChannels
from gyrocal.instruments.gyro.datagram import encode_frame_array
from gyrocal.instruments.gyro.datagram_types import FrameLayout, counter_step, counter_values

#: specific force a level unit at rest measures, g (x, y, z)
LEVEL_SPECIFIC_FORCE_G = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class SpecificForce:
    """What one block of frames carries on its acceleration channels, g, (n, 3) each."""

    acc_g: np.ndarray      # the accelerometers' outputs (with their errors and noise)
    incl_g: np.ndarray     # the inclinometers' outputs


#: (frame times, sensor temperature or None) → the block's accelerometer and inclinometer outputs
SpecificForceSource = Callable[[np.ndarray, "np.ndarray | None"], SpecificForce]


def encode_sim_frames(k: np.ndarray, rate: np.ndarray, temp_c: np.ndarray | None, *,
                      layout: FrameLayout, lsb: float, latency_us: int, sample_rate_hz: float,
                      accelerometer_range_g: int, force: SpecificForce | None = None) -> np.ndarray:
    """Datagrams (rows) for grid frames ``k`` with rates ``rate`` (n, 3) and temperatures (n, 3).

    ``force``: the acceleration channels of a simulated IMU; None: a unit level and at rest.
    """
    n = k.size
    if force is None:
        gravity = np.broadcast_to(np.asarray(LEVEL_SPECIFIC_FORCE_G), (n, 3))
        force = SpecificForce(gravity, gravity)
    kind = layout.kind
    channels = SensorChannels(acc_g=force.acc_g if kind.acceleration else None,
                              incl_g=force.incl_g if kind.inclination else None)
    counter = counter_values(np.asarray(k, dtype=np.int64), counter_step(sample_rate_hz))
    return encode_frame_array(rate, counter, temp_c=temp_c if kind.temperature else None,
                              latency_us=latency_us, lsb=lsb, crlf=layout.crlf,
                              datagram=layout.identifier, channels=channels,
                              accelerometer_range_g=accelerometer_range_g)
