"""A whole simulated station: chamber, table and gyro servers sharing one clock and one physics.

``gyrocal run --sim`` and ``gyrocal sim serve`` build one of these from a
station file's ``simulation:`` section. The servers are the same ones the
tests talk to — a Modbus server, an ACUTROL command-language socket server, a pseudo-terminal —
so a dry run exercises the real drivers end to end. The simulated gyro sees
the table's true rate and angle and the chamber's true air temperature at
each frame time, through the measurement model in ``models/``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from gyrocal.instruments.driver_spec import DriverSpec, Role, SimRequest, SimServer
from gyrocal.instruments.registry import registry
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.imu_source import FIXTURE_FAULTS, ImuPhysicsSource, SimulatedFixture
from gyrocal.instruments.sim.replay_pty import ReplayGyroPort
from gyrocal.instruments.sim.tilt_force import TiltForce
from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import RealClock, SimClock
from gyrocal.models.drive_interference import DriveInterference
from gyrocal.models.gyro_model import GyroModel
from gyrocal.models.gyro_sim import GyroSimulator
from gyrocal.models.imu_model import ImuModel, load_any_model
from gyrocal.models.seeding import attempt_seed
from gyrocal.models.sim_state import SimStateError, capture, restore
from gyrocal.models.table import TablePhysics


@runtime_checkable
class CoilCurrents(Protocol):
    """A simulated supply that says what current each channel drives (a coil on it)."""

    def output_current_a(self, channel: int) -> float: ...


@runtime_checkable
class StartingUnit(Protocol):
    """A simulated unit that sends something when it starts (a STIM300's start-up datagrams):
    it asks ``starts_from`` when it begins to send."""

    starts_from: Callable[[], float | None] | None


@runtime_checkable
class HearsCommands(Protocol):
    """A simulated gyro that takes the commands its reader writes (``gyro_pty.py``)."""

    def hear_command(self) -> bool: ...


@runtime_checkable
class CountsMadeBytes(Protocol):
    """A simulated gyro on simulated time that counts the bytes it made for the reader."""

    def bytes_made(self) -> int: ...


@runtime_checkable
class SwitchedOutput(Protocol):
    """A simulated supply that says when a channel's output was switched on (None: off)."""

    def on_since_s(self, channel: int) -> float | None: ...


@dataclass
class UnitPower:
    """The simulated unit on a supply channel: silent while the output is off and for
    ``startup_s`` after it is switched on; its warm-up transient starts at the switch-on."""

    #: what a resumed dry run restores (models/sim_state.py): the power-on offsets drawn
    #: so far and their stream
    SIM_STATE = ("_rng", "_offsets")

    supply: SwitchedOutput
    channel: int
    startup_s: float
    #: 1 σ of the bias offset each power-on draws (turn-on-to-turn-on repeatability), deg/h
    turn_on_bias_dph: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._offsets: dict[float, float] = {}

    def on_since_s(self) -> float | None:
        return self.supply.on_since_s(self.channel)

    def sends_from_s(self) -> float | None:
        """When the unit, switched on, begins to send (None: off): after its start-up delay."""
        on_s = self.on_since_s()
        return None if on_s is None else on_s + self.startup_s

    def turn_on_offset_dph(self, on_s: float) -> float:
        """The offset of the power-on at ``on_s``: each new power-on draws the next value of
        one seeded stream, so it is the same for every block of that power-on."""
        if self.turn_on_bias_dph == 0.0:
            return 0.0
        if on_s not in self._offsets:
            self._offsets[on_s] = float(self._rng.normal(0.0, self.turn_on_bias_dph))
        return self._offsets[on_s]


#: Seed offsets so the chamber, table and gyro noise streams are independent.
_SEED_CHAMBER, _SEED_TABLE, _SEED_GYRO, _SEED_PTY, _SEED_DRIVE = 101, 202, 303, 404, 505
_SEED_TILT = 606
_SEED_POWER = 707


class GyroPhysicsSource:
    """Feeds the simulated gyro: model output for the table/chamber state at each frame time."""

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("simulator", "interference", "skipped_s")

    def __init__(self, simulator: GyroSimulator, table: TablePhysics, chamber: ChamberPhysics,
                 start_s: float, skip_step_s: float = 1.0,
                 interference: DriveInterference | None = None,
                 field: Callable[[], float] | None = None) -> None:
        self.simulator = simulator
        #: the supply the unit runs from; None: always powered, warm-up from the start
        self.power: UnitPower | None = None
        #: the magnetic field along the gyro's sensitive axis now (T); None: no coil
        self.field = field
        #: what the table's drive adds while powered (interlock closed); None: nothing
        self.interference = interference
        self.table = table
        self.chamber = chamber
        self.start_s = float(start_s)
        self.skip_step_s = skip_step_s
        self.skipped_s = 0.0

    def _inputs(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # Frames on the gyro's grid may start a fraction of a frame before the physics
        # existed (real time runs on while the servers start): that instant's state is
        # the initial one, so clamp to it rather than ask the physics for its prehistory.
        t_q = np.maximum(t_s, self.start_s)
        return (np.asarray(self.table.rate_dps(t_q), dtype=float),
                np.asarray(self.chamber.air_temperature_c(t_q), dtype=float),
                np.asarray(self.table.angle_deg(t_q), dtype=float))

    def reseed(self, seed: np.random.SeedSequence) -> None:
        self.simulator.reseed(seed)

    def inputs_at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Table rate, chamber air temperature and table angle at the frame times."""
        return self._inputs(t_s)

    def emit(self, t_s: np.ndarray, inputs: tuple[np.ndarray, np.ndarray, np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
        """The model's output for frames at ``t_s`` seeing ``inputs`` (a gap is skipped first)."""
        sim = self.simulator
        gap_s = float(t_s[0]) - sim.t_next_s
        if gap_s > 0.5 / sim.fs_hz:
            sim.skip_to(float(t_s[0]), self._inputs, self.skip_step_s)
            self.skipped_s += gap_s
        field_t = None if self.field is None else self.field()
        samples = sim.generate(*inputs, field_t=field_t)
        gyro = samples.gyro
        if self.interference is not None and self.table.interlock_closed:
            gyro = gyro + self.interference(t_s) / 3600.0 * sim.model.scale_factor
        if self.power is not None:
            gyro = self._powered(t_s, gyro)
        return gyro, samples.sensor_temp_c

    def catch_up(self, t_s: float) -> None:
        """Evolve the unit's physics (thermal lag, hysteresis, angle) to the first frame
        at or after ``t_s`` without emitting, as :meth:`emit` does first for a gap; a
        snapshot then holds the state of now, not of the last frame read."""
        sim = self.simulator
        t_frame_s = math.ceil(t_s * sim.fs_hz - 1e-6) / sim.fs_hz
        gap_s = t_frame_s - sim.t_next_s
        if gap_s > 0.5 / sim.fs_hz:
            sim.skip_to(t_frame_s, self._inputs, self.skip_step_s)
            self.skipped_s += gap_s

    def _powered(self, t_s: np.ndarray, gyro: np.ndarray) -> np.ndarray:
        """NaN (no frame) where the unit is off or still starting; the warm-up transient
        (the model's A·e^(−t/τ) from the clock's origin) moved to start at the switch-on."""
        assert self.power is not None
        on_s = self.power.on_since_s()
        if on_s is None:
            return np.full_like(gyro, np.nan)
        gyro = np.where(t_s >= on_s + self.power.startup_s, gyro, np.nan)
        warmup = self.simulator.model.effect("warmup_transient")
        if warmup is not None:
            amplitude_dph, tau_s = float(warmup["amplitude_dph"]), float(warmup["tau_s"])
            shift_dph = amplitude_dph * (np.exp(-(t_s - on_s) / tau_s) - np.exp(-t_s / tau_s))
            gyro = gyro + shift_dph / 3600.0 * self.simulator.model.scale_factor
        offset_dph = self.power.turn_on_offset_dph(on_s)
        return gyro + offset_dph / 3600.0 * self.simulator.model.scale_factor

    def __call__(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.emit(t_s, self._inputs(t_s))


@dataclass(frozen=True)
class SimAddresses:
    chamber: str
    table: str
    gyro: str
    supply: str | None = None


class SimulatedStation:
    """Starts/stops the three simulators of a station; exposes their addresses and faults."""

    def __init__(self, station, clock: RealClock | SimClock, seed: int | None = None,
                 model: GyroModel | ImuModel | None = None, gyro_block_frames: int | None = None,
                 sample_rate_hz: float | None = None,
                 gyro_port: ReplayGyroPort | None = None, unit_serial: str | None = None) -> None:
        """``gyro_port``: a replayed capture to serve as the gyro instead of the simulated one;
        ``unit_serial``: the serial the simulated unit reports (the procedure's unit under test)."""
        self.unit_serial = unit_serial
        sim = station.simulation
        if sim is None:
            raise ValueError(f"{station.file}: the station has no simulation: section; "
                             "--sim needs one (gyro_model, seed, chamber and table physics)")
        self.station = station
        self.clock = clock
        self.seed = sim.seed if seed is None else int(seed)
        # A version-2 model file is a three-axis IMU on a hexahedron fixture; version 1 is
        # the single-axis gyro every other procedure calibrates.
        self.model = model if model is not None else load_any_model(sim.gyro_model)
        self.chamber_physics, self.table_physics = self._physics(station, sim, clock)
        # A real STIM300 is configured for its output rate; the simulated one takes
        # the procedure's rate so dry runs log exactly what the procedure asks for.
        self.sample_rate_hz = float(sample_rate_hz or station.gyro.sample_rate_hz)
        specs, supply_spec = self._fault_injectors(station)
        self.fixture: SimulatedFixture | None = None
        self.source: GyroPhysicsSource | ImuPhysicsSource = self._physics_source(station, sim)
        #: the table turned on its side tilts the unit through gravity (tilt_linearity)
        self.tilt: TiltForce | None = None
        if station.table.orientation == "horizontal" and isinstance(self.source, GyroPhysicsSource):
            self.tilt = TiltForce(self.table_physics, station.site.gravity_g, sim.inclinometer,
                                  self.seed + _SEED_TILT)
        self._start_servers(station, sim, specs, supply_spec, gyro_block_frames, gyro_port)
        self._started = False

    def _physics(self, station, sim, clock: RealClock | SimClock
                 ) -> tuple[ChamberPhysics, TablePhysics]:
        """The chamber's air and the table's axis, within the station's limits."""
        limits = station.chamber.limits
        chamber = ChamberPhysics(
            clock,
            ambient_c=sim.chamber.ambient_c,
            tau_s=sim.chamber.tau_s,
            max_heat_c_per_min=sim.chamber.max_heat_c_per_min,
            max_cool_c_per_min=sim.chamber.max_cool_c_per_min,
            min_setpoint_c=limits.min_temp_c,
            max_setpoint_c=limits.max_temp_c,
            noise_c=sim.chamber.noise_c,
            seed=self.seed + _SEED_CHAMBER,
        )
        table_limits = station.table.limits
        table = TablePhysics(
            clock,
            max_rate_dps=table_limits.max_rate_dps,
            max_accel_dps2=table_limits.max_accel_dps2,
            rate_noise_dps=sim.table.rate_noise_dps,
            seed=self.seed + _SEED_TABLE,
        )
        return chamber, table

    def _fault_injectors(self, station) -> tuple[dict[Role, DriverSpec], DriverSpec | None]:
        """One fault injector per simulator, with the faults its driver's simulator knows."""
        self.fixture_faults = FaultInjector(FIXTURE_FAULTS, owner="simulated fixture")
        specs = {role: registry().get(role, config.driver) for role, config in (
            (Role.CHAMBER, station.chamber), (Role.TABLE, station.table),
            (Role.GYRO, station.gyro))}
        self.chamber_faults = FaultInjector(specs[Role.CHAMBER].sim_faults, owner="simulated chamber")
        self.table_faults = FaultInjector(specs[Role.TABLE].sim_faults, owner="simulated table")
        self.gyro_faults = FaultInjector(specs[Role.GYRO].sim_faults, owner="simulated gyro")
        supply_spec = registry().get(Role.SUPPLY, station.supply.driver) if station.supply else None
        self.supply_faults = FaultInjector(supply_spec.sim_faults if supply_spec else (),
                                           owner="simulated supply")
        return specs, supply_spec

    def _physics_source(self, station, sim) -> GyroPhysicsSource | ImuPhysicsSource:
        """The unit's physics: an IMU on the fixture, or the single-axis gyro with drive lines."""
        if isinstance(self.model, ImuModel):
            self.fixture = SimulatedFixture(self.fixture_faults)
            return ImuPhysicsSource(
                self.model, self.sample_rate_hz, self.seed + _SEED_GYRO, self.table_physics,
                self.chamber_physics, station.site.latitude_deg, self.fixture,
                start_s=self.clock.now_s(), gravity_g=station.site.gravity_g)
        self.gyro_simulator = GyroSimulator(self.model, self.sample_rate_hz,
                                            seed=self.seed + _SEED_GYRO)
        drive = DriveInterference(sim.table.drive_lines, sim.table.drive_noise_dph,
                                  self.sample_rate_hz, self.seed + _SEED_DRIVE)
        return GyroPhysicsSource(self.gyro_simulator, self.table_physics,
                                 self.chamber_physics, start_s=self.clock.now_s(),
                                 interference=drive if drive.active else None)

    def _start_servers(self, station, sim, specs: dict[Role, DriverSpec],
                       supply_spec: DriverSpec | None, gyro_block_frames: int | None,
                       gyro_port: ReplayGyroPort | None) -> None:
        """Each instrument's simulator (or the replayed gyro), and the coil and power hooks."""
        if gyro_block_frames is None:
            # Per block the model is evaluated once (its fixed cost is ~0.2 ms), so blocks must
            # be large; 512 frames (0.26 s at 2 kHz, 2 s at 250 Hz) keeps that cost under 1 µs a
            # frame while the clock runs at most one block ahead of what the reader consumed.
            gyro_block_frames = 512
        self.chamber_server = _simulator(specs[Role.CHAMBER], self._request(
            station.chamber.settings, self.chamber_faults))
        self.table_server = _simulator(specs[Role.TABLE], self._request(
            station.table.settings, self.table_faults))
        self.supply_server: SimServer | None = None
        if supply_spec is not None:
            self.supply_server = _simulator(supply_spec, self._request(
                station.supply.settings, self.supply_faults))
        if station.coil is not None and isinstance(self.source, GyroPhysicsSource):
            self.source.field = self._coil_field(station.coil)
        if sim.gyro_startup_s is not None and isinstance(self.source, GyroPhysicsSource):
            self.source.power = self._unit_power(station, sim.gyro_startup_s,
                                                 sim.turn_on_bias_dph)
        self.gyro_port: SimServer
        if gyro_port is not None:
            self.gyro_port = gyro_port
        else:
            request = self._request({**station.gyro.settings, "_block_frames": gyro_block_frames},
                                    self.gyro_faults, seed_offset=_SEED_PTY)
            self.gyro_port = _simulator(specs[Role.GYRO], request)
            power = self.source.power if isinstance(self.source, GyroPhysicsSource) else None
            if power is not None and isinstance(self.gyro_port, StartingUnit):
                self.gyro_port.starts_from = power.sends_from_s

    def _coil_field(self, coil) -> Callable[[], float]:
        """B along the gyro's sensitive axis: the coil constant × (I(+) - I(-)) of the simulated
        supply's coil channels when the coil's axis is the input axis, else 0."""
        supply = self.supply_server
        if not isinstance(supply, CoilCurrents):
            raise ValueError(f"{self.station.file}: the coil needs a simulated supply that "
                             "reports its channels' currents; this one does not")
        along = 1.0 if coil.axis == "input" else 0.0

        def field_t() -> float:
            return along * coil.constant_t_per_a * (supply.output_current_a(coil.positive_channel)
                                                    - supply.output_current_a(coil.negative_channel))
        return field_t

    def _unit_power(self, station, startup_s: float, turn_on_bias_dph: float) -> UnitPower:
        """The unit follows the simulated supply's output (turn-on steps switch it)."""
        supply = self.supply_server
        if station.supply is None or not isinstance(supply, SwitchedOutput):
            raise ValueError(f"{station.file}: simulation.gyro_startup_s needs a supply: section "
                             "whose simulator reports when its output was switched on")
        return UnitPower(supply, int(station.supply.settings.get("channel") or 1), startup_s,
                         turn_on_bias_dph, self.seed + _SEED_POWER)

    def begin_attempt(self, step_id: str, attempt: int) -> None:
        """Every simulator draws from (seed, step id, attempt) from here (``models/seeding.py``).

        Called by the run before an attempt's first sample, in the controller's
        thread: with the stream made on demand (``gyro_pty.py``), two runs with
        one seed give the same samples bit for bit, however long a simulator
        idled before the attempt.
        """
        if self.seed is None:       # no seed: fresh entropy, nothing to reproduce
            return
        # a fifth child for the supply: the first four are the same whether it is drawn or not
        chamber, table, gyro, pty, supply = attempt_seed(self.seed, step_id, attempt).spawn(5)
        self.chamber_physics.reseed(chamber)
        self.table_physics.reseed(table)
        self.source.reseed(gyro)
        self.gyro_port.reseed(pty)
        if self.supply_server is not None:
            self.supply_server.reseed(supply)

    def snapshot(self) -> dict[str, Any] | None:
        """The station's simulated state now, as JSON data; None when it cannot all be kept.

        Taken when a step is journaled complete; a resumed dry run restores the
        last one (:meth:`restore`) before its first remaining step, so it goes on
        from the very state the interrupted session reached: the simulated time,
        the chamber's air and setpoint, the table's motion and mode, the gyro's
        (or each IMU axis's) noise, Markov and walk levels, thermal lag and
        hysteresis, the frame grid or the SCPI gyro's reading memory, the supply's
        outputs and the powered unit's turn-on draws, the fixture's mounting, the
        inclinometers' and accelerometers' noise, and every random stream. None on
        a real-time clock (``--speed N``) or with a replayed capture (its bytes run
        in wall time): such a run resumes as a real one does, from its own re-soak.
        """
        if not self._keeps_everything():
            return None
        port = capture(self.gyro_port)      # first: waits for the frames in making
        # the unit's physics brought to now: idle tails, which carried it along while
        # nobody read, are made only when read (gyro_pty.py)
        self.source.catch_up(self.clock.now_s())
        state = {"clock_s": self.clock.now_s(), "gyro_port": port,
                 "chamber": capture(self.chamber_physics), "table": capture(self.table_physics),
                 "gyro": capture(self.source)}
        return state | {name: capture(part) for name, part in self._optional_parts().items()}

    def _optional_parts(self) -> dict[str, Any]:
        """The simulators this station has beyond chamber, table and gyro, by snapshot key."""
        parts: dict[str, Any] = {}
        if self.supply_server is not None:
            parts["supply"] = self.supply_server
        if isinstance(self.source, GyroPhysicsSource) and self.source.power is not None:
            parts["unit_power"] = self.source.power
        if self.tilt is not None:
            parts["tilt"] = self.tilt
        return parts

    def restore(self, state: dict[str, Any]) -> bool:
        """Put the station back into ``state`` (from :meth:`snapshot` of this station).

        False (nothing restored) when this station keeps no snapshot (a resumed dry
        run on a real-time clock, ``--speed N``). A snapshot that does not fit
        (an edited journal, another station) is a :class:`SimStateError`.
        """
        if not self._keeps_everything() or not isinstance(self.clock, SimClock):
            return False
        parts = self._optional_parts()
        extra = set(state) - {"clock_s", "gyro_port", "chamber", "table", "gyro"} - set(parts)
        if extra:
            raise SimStateError(f"snapshot holds {sorted(extra)}, which this station has not")
        try:
            restore(self.gyro_port, state["gyro_port"])
            self.clock.restore_s(float(state["clock_s"]))
            restore(self.chamber_physics, state["chamber"])
            restore(self.table_physics, state["table"])
            restore(self.source, state["gyro"])
            for name, part in parts.items():
                restore(part, state[name])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            if isinstance(exc, SimStateError):
                raise
            raise SimStateError(f"{type(exc).__name__}: {exc}") from None
        return True

    def gyro_bytes_waiting(self) -> Callable[[], bool] | None:
        """Whether the simulated STIM300 made bytes since the last call (``gyro_pty.py``): a
        first-frame poll's question; None for a gyro that cannot tell (a replay, a SCPI gyro)."""
        port = self.gyro_port
        if not isinstance(port, CountsMadeBytes) or not isinstance(self.clock, SimClock):
            return None
        seen = [port.bytes_made()]

        def made_since() -> bool:
            before, seen[0] = seen[0], port.bytes_made()
            return seen[0] > before
        return made_since

    def gyro_command_heard(self) -> Callable[[], bool] | None:
        """What the driver waits for after writing a command on simulated time: the simulated
        STIM300 has taken it off the pty (``gyro_pty.hear_command``), so where its answer
        falls depends on the controller's calls alone; None for a gyro that takes none."""
        port = self.gyro_port
        if not isinstance(port, HearsCommands) or not isinstance(self.clock, SimClock):
            return None
        return port.hear_command

    def _keeps_everything(self) -> bool:
        """Simulated time, a seed, and a gyro whose state the codec knows (a replayed
        capture's is not: ``replay_pty.py`` writes it in wall time)."""
        port = self.gyro_port
        return (isinstance(self.clock, SimClock) and self.seed is not None
                and (callable(getattr(port, "sim_state", None)) or hasattr(port, "SIM_STATE")))

    def _request(self, settings, faults: FaultInjector, seed_offset: int = 0) -> SimRequest:
        """What every simulator of this station sees: its settings and faults, and the shared bench."""
        return SimRequest(settings=settings, faults=faults, clock=self.clock,
                          seed=self.seed + seed_offset, chamber=self.chamber_physics,
                          table=self.table_physics, gyro_source=self.source,
                          sample_rate_hz=self.sample_rate_hz, unit_serial=self.unit_serial,
                          specific_force=(self.source.specific_force
                                          if isinstance(self.source, ImuPhysicsSource)
                                          else self.tilt))

    @property
    def addresses(self) -> SimAddresses:
        return SimAddresses(self.chamber_server.address, self.table_server.address,
                            self.gyro_port.address,
                            self.supply_server.address if self.supply_server else None)

    def _servers(self) -> list[SimServer]:
        servers = [self.chamber_server, self.table_server, self.gyro_port]
        return servers + ([self.supply_server] if self.supply_server is not None else [])

    def start(self) -> SimulatedStation:
        if not self._started:
            for server in self._servers():
                server.start()
            self._started = True
        return self

    def stop(self) -> None:
        for server in reversed(self._servers()):
            with contextlib.suppress(Exception):
                server.stop()
        self._started = False

    def __enter__(self) -> SimulatedStation:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _simulator(spec: DriverSpec, request: SimRequest) -> SimServer:
    if spec.simulator is None:
        raise ValueError(f"{spec.role.value} driver {spec.name!r} ({spec.origin}) has no simulator; "
                         "--sim and `gyrocal sim serve` cannot stand in for it")
    return spec.simulator(request)
