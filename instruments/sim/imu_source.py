"""A simulated three-axis IMU on a hexahedron fixture, on the simulated rate table.

The fixture holds the IMU in one of its mountings (which axis points up
along the table axis). Its body rate is the table rate plus the Earth rate,
both turned into IMU axes (``models/imu_model.py``); the misalignment
matrix mixes them, and each axis is then a complete single-axis gyro model
(bias, scale factor, temperature, noise, effects) with its own noise seed.

In a dry run nobody stands at the table, so the fixture turns by itself
when the run asks for a remount. The ``wrong_mount`` fault makes it turn to
the wrong face (the next axis up, as a tired operator might), which the
run's mount check must catch before it calibrates anything.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.gyro_frames import SpecificForce
from gyrocal.models.gyro_sim import GyroSimulator
from gyrocal.models.imu_model import ImuModel, Mounting, body_rate_dps, specific_force_imu_g

FIXTURE_FAULTS = ("wrong_mount",)
#: Where the fixture stands before the first remount: IMU +Z up (how it ships).
HOME_MOUNTING = Mounting(2, 1.0)


class SimulatedFixture:
    """The hexahedron fixture: its current mounting, turned on request."""

    #: what a resumed dry run restores (models/sim_state.py): the face it stands on
    SIM_STATE = ("_mounting",)

    def __init__(self, faults: FaultInjector | None = None,
                 mounting: Mounting = HOME_MOUNTING) -> None:
        self.faults = faults if faults is not None else FaultInjector(FIXTURE_FAULTS,
                                                                      owner="simulated fixture")
        self._lock = threading.Lock()
        self._mounting = mounting

    @property
    def mounting(self) -> Mounting:
        with self._lock:
            return self._mounting

    def mount(self, requested: Mounting) -> Mounting:
        """Turn the fixture; returns the mounting it really ended in."""
        actual = requested
        if self.faults.take("wrong_mount") is not None:
            actual = Mounting((requested.up_axis + 1) % 3, requested.sign)
        with self._lock:
            self._mounting = actual
        return actual


class ImuPhysicsSource:
    """Feeds the simulated gyro port all three axes for the table/chamber state at each frame."""

    #: what a resumed dry run restores (models/sim_state.py): each axis's gyro state, the
    #: accelerometers' noise stream and the fixture's mounting
    SIM_STATE = ("simulators", "_acc_rng", "fixture")

    def __init__(self, model: ImuModel, fs_hz: float, seed: int, table, chamber,
                 latitude_deg: float, fixture: SimulatedFixture, start_s: float,
                 skip_step_s: float = 1.0, gravity_g: float = 1.0) -> None:
        self.model = model
        self.fs_hz = float(fs_hz)
        self.gravity_g = float(gravity_g)        # local gravity in standard g (models/gravity.py)
        self._acc_rng = np.random.default_rng(seed + 104729)
        self.simulators = [GyroSimulator(axis, fs_hz, seed=seed + 7919 * i)
                           for i, axis in enumerate(model.axes)]
        self.table = table
        self.chamber = chamber
        self.latitude_deg = float(latitude_deg)
        self.fixture = fixture
        self.start_s = float(start_s)
        self.skip_step_s = skip_step_s

    def _state(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t_q = np.maximum(t_s, self.start_s)    # no physics before the servers started
        return (np.asarray(self.table.rate_dps(t_q), dtype=float),
                np.asarray(self.chamber.air_temperature_c(t_q), dtype=float),
                np.asarray(self.table.angle_deg(t_q), dtype=float))

    def axis_inputs(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(input rate per axis (n, 3) deg/s, chamber °C, table angle) at ``t_s``."""
        rate, chamber, angle = self._state(t_s)
        body = body_rate_dps(self.fixture.mounting, rate, angle, self.latitude_deg)
        # E changes with temperature by µrad per kelvin: one value per block is exact
        # to far below the noise (a block is at most a few seconds).
        mix = np.eye(3) + self.model.misalignment_rad(float(np.mean(chamber)))
        return body @ mix.T, chamber, angle

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """One child stream per axis."""
        for sim, child in zip(self.simulators, seed.spawn(len(self.simulators)), strict=True):
            sim.reseed(child)

    def inputs_at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(input rate per axis (n, 3), chamber °C, table angle), in the fixture's mounting now."""
        return self.axis_inputs(np.asarray(t_s, dtype=float))

    def emit(self, t_s: np.ndarray, inputs: tuple[np.ndarray, np.ndarray, np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
        """All three axes for frames at ``t_s`` seeing ``inputs`` (a gap is skipped first)."""
        t_s = np.asarray(t_s, dtype=float)
        self._skip_to(float(t_s[0]))
        rates, chamber, angle = inputs
        outputs = []
        sensor = None
        for axis, sim in enumerate(self.simulators):
            samples = sim.generate(rates[:, axis], chamber, angle)
            outputs.append(samples.gyro)
            sensor = samples.sensor_temp_c if sensor is None else sensor
        return np.stack(outputs, axis=1), sensor

    def _skip_to(self, t0_s: float) -> None:
        """Evolve every axis without emitting up to the frame at ``t0_s`` (a gap)."""
        first = self.simulators[0]
        if t0_s - first.t_next_s > 0.5 / first.fs_hz:
            for axis, sim in enumerate(self.simulators):
                def inputs_at(grid: np.ndarray, axis: int = axis):
                    rates, chamber, angle = self.axis_inputs(grid)
                    return rates[:, axis], chamber, angle
                sim.skip_to(t0_s, inputs_at, self.skip_step_s)

    def catch_up(self, t_s: float) -> None:
        """Evolve the axes to the first frame at or after ``t_s`` without emitting, as a gap
        is skipped first: a snapshot then holds the state of now (``station_sim.py``)."""
        self._skip_to(math.ceil(t_s * self.fs_hz - 1e-6) / self.fs_hz)

    def __call__(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t_s = np.asarray(t_s, dtype=float)
        return self.emit(t_s, self.axis_inputs(t_s))

    def specific_force(self, t_s: np.ndarray, sensor_temp_c: np.ndarray | None) -> SpecificForce:
        """The acceleration channels for frames at ``t_s``: gravity in the current mounting.

        The accelerometers see the specific force through their own errors
        (``models/imu_accel.py``) at the block's mean sensor temperature (a
        block is seconds long; the errors move by µg per kelvin); the
        inclinometers, which the model does not describe, read it as it is.
        """
        n = np.asarray(t_s).size
        truth = np.broadcast_to(specific_force_imu_g(self.fixture.mounting, self.gravity_g), (n, 3))
        acc = self.model.accelerometers
        if acc is None:
            return SpecificForce(np.array(truth), np.array(truth))
        if sensor_temp_c is not None:
            temp_c = float(np.mean(sensor_temp_c))
        else:
            temp_c = float(np.mean(self._state(np.asarray(t_s, dtype=float))[1]))
        return SpecificForce(acc.indicate(truth, temp_c, self.fs_hz, self._acc_rng), np.array(truth))
