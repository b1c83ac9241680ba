"""What the simulated unit's accelerometers and inclinometers read on a table turned on its side.

With the table axis horizontal (station ``table.orientation: horizontal``) the
table is the tilt test's indexing head: turning it by θ about the unit's y axis
tips the unit's x axis out of the horizontal, so gravity reads a_x = g·sin θ,
a_y = 0, a_z = g·cos θ (θ = 0: level, the unit's z up, as the level unit of
``gyro_frames.py``). The accelerometers read that as it is; the inclinometers
through the station's simulated errors (``simulation.inclinometer``): the x
channel scale·a_x + quadratic·a_x² + bias, the y channel cross_axis·a_x (the
leak across its sensitive axis the lateral-sensitivity test measures), each with
white noise.
"""

from __future__ import annotations

import numpy as np

from gyrocal.instruments.sim.gyro_frames import SpecificForce
from gyrocal.models.table import TablePhysics


class TiltForce:
    """(frame times, sensor temperature) -> the block's acceleration channels, g."""

    #: what a resumed dry run restores (models/sim_state.py): the inclinometers' noise stream
    SIM_STATE = ("_rng",)

    def __init__(self, table: TablePhysics, gravity_g: float, inclinometer, seed: int) -> None:
        self.table, self.gravity_g, self.errors = table, float(gravity_g), inclinometer
        self._rng = np.random.default_rng(seed)

    def reseed(self, seed: np.random.SeedSequence) -> None:
        self._rng = np.random.default_rng(seed)

    def truth_g(self, t_s: np.ndarray) -> np.ndarray:
        theta = np.radians(np.asarray(self.table.angle_deg(np.asarray(t_s, dtype=float)),
                                      dtype=float))
        theta = np.atleast_1d(theta)
        return self.gravity_g * np.column_stack([np.sin(theta), np.zeros_like(theta),
                                                 np.cos(theta)])

    def __call__(self, t_s: np.ndarray, sensor_temp_c: np.ndarray | None = None) -> SpecificForce:
        truth = self.truth_g(t_s)
        e = self.errors
        a_x = truth[:, 0]
        incl = np.column_stack([e.scale * a_x + e.quadratic_per_g * a_x**2 + e.bias_g,
                                e.cross_axis * a_x, truth[:, 2]])
        if e.noise_g > 0:
            incl = incl + self._rng.normal(0.0, e.noise_g, incl.shape)
        return SpecificForce(truth, incl)
