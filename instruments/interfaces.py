"""The instrument roles the orchestrator needs, as small typed interfaces.

The orchestrator only ever sees these; a new chamber or table model is a new
driver class that satisfies one of them, nothing else changes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from gyrocal.instruments.gyro.channels import SensorChannels
from gyrocal.instruments.gyro.configuration_query import ConfigurationAnswer
from gyrocal.instruments.gyro.identity_query import IdentityAnswer, StartUpRecord


@dataclass(frozen=True)
class Identity:
    """What an instrument says it is (for the manifest and the report)."""

    role: str          # "chamber", "table" or "gyro"
    driver: str        # e.g. "watlow_f4"
    address: str       # e.g. "socket://127.0.0.1:5020"
    description: str   # e.g. "*IDN?" reply or model register contents


@dataclass(frozen=True)
class ChamberStatus:
    temperature_c: float
    setpoint_c: float
    alarm: bool
    detail: str = ""
    profile_running: bool = False   # the controller runs (or holds) its own profile
    run_state: str = ""


@dataclass(frozen=True)
class ChamberUnits:
    """How a controller speaks temperatures on its bus, as read from it (not as configured)."""

    fahrenheit: bool
    decimals: int | None     # implied decimals of an integer register; None for floats
    source: str              # the registers it was read from, e.g. "registers 901, 606"


@runtime_checkable
class ReportsUnits(Protocol):
    def read_units(self) -> ChamberUnits: ...


@dataclass(frozen=True)
class TableStatus:
    rate_dps: float
    position_deg: float
    interlock_closed: bool


@runtime_checkable
class Chamber(Protocol):
    def identify(self) -> Identity: ...
    def read_temperature_c(self) -> float: ...
    def read_setpoint_c(self) -> float: ...
    def set_setpoint_c(self, setpoint_c: float) -> None: ...
    def read_status(self) -> ChamberStatus: ...
    def reset_link(self) -> None:
        """Drop the connection and whatever is buffered in it; the next command opens a fresh one."""
    def close(self) -> None: ...


@dataclass(frozen=True)
class SupplyReading:
    """What the supply powering the unit under test reads back."""

    voltage_v: float
    current_a: float
    output_on: bool


@runtime_checkable
class PowerSupply(Protocol):
    """The programmable supply of the unit under test (one output channel)."""

    name: str

    def identify(self) -> Identity: ...
    def configure(self, voltage_v: float, current_limit_a: float) -> None: ...
    def set_output(self, on: bool) -> None: ...
    def read(self) -> SupplyReading: ...
    def reset_link(self) -> None: ...
    def close(self) -> None: ...


@runtime_checkable
class PositionTable(Protocol):
    """A table that also serves position mode (the tilt test's indexing head); optional."""

    def set_position_mode(self) -> None: ...
    def set_position_deg(self, position_deg: float) -> None: ...


@runtime_checkable
class HoldingTable(Protocol):
    """A table that can stop and keep its axis under servo (a horizontal axis with an
    unbalanced load swings down if the servo is switched off); optional."""

    def hold(self) -> None: ...
    def read_servo_mode(self) -> str: ...


@runtime_checkable
class RateTable(Protocol):
    def identify(self) -> Identity: ...
    def interlock_closed(self) -> bool: ...
    def close_interlock(self) -> None: ...
    def open_interlock(self) -> None: ...
    def set_rate_mode(self) -> None: ...
    def set_acceleration_limit_dps2(self, accel_dps2: float) -> None: ...
    def set_rate_dps(self, rate_dps: float) -> None: ...
    def read_rate_dps(self) -> float: ...
    def read_position_deg(self) -> float: ...
    def read_status(self) -> TableStatus: ...
    def stop(self) -> None: ...
    def reset_link(self) -> None:
        """Drop the session and whatever is buffered in it; the next command opens a fresh one."""
    def close(self) -> None: ...


@runtime_checkable
class SynthesisTable(RateTable, Protocol):
    """A rate table that also turns sinusoids (ACUTROL synthesis mode, TM-8004 §4.7.6):
    what a frequency-response step needs beyond rate mode."""

    def set_oscillator(self, magnitude: float, frequency_hz: float, phase_deg: float) -> None: ...
    def set_synthesis_mode(self) -> None: ...


@dataclass
class GyroBlock:
    """Decoded gyro samples: only frames whose CRC checked, in arrival order.

    ``counter`` is the datagram counter (wraps at 256); gaps in it are lost
    frames and are counted, never papered over.
    """

    rate: np.ndarray                 # gyro output in the unit's output units
    counter: np.ndarray              # uint8 datagram counter
    index: np.ndarray                # int64 frame index since the last flush, counter gaps unwrapped
    status: np.ndarray               # uint8 status byte (0 = OK)
    temperature_c: np.ndarray | None = None
    crc_errors: int = 0              # frames dropped because the CRC failed
    lost_frames: int = 0             # counter gaps (frames never received)
    garbage_bytes: int = 0           # bytes skipped while re-synchronising
    extra: dict = field(default_factory=dict)
    rate_xyz: np.ndarray | None = None     # (n, 3) all three axes of a multi-axis unit; ``rate`` is the unit under test
    flagged: np.ndarray | None = None      # bool per sample: the status byte marks it not valid for the unit under test
    #: accelerometers, inclinometers, per-sensor temperatures and statuses, where the datagram has them
    channels: SensorChannels | None = None

    def __len__(self) -> int:
        return int(self.rate.shape[0])

    @property
    def flagged_count(self) -> int:
        """Samples the unit itself marks as saturated or in error (bad data, like lost frames)."""
        return 0 if self.flagged is None else int(np.count_nonzero(self.flagged))


@runtime_checkable
class GyroStream(Protocol):
    name: str      # the instrument name its errors carry (InstrumentError.instrument)

    def identify(self) -> Identity: ...
    def flush(self) -> None:
        """Discard everything buffered so the next samples are fresh."""
    def read_samples(self, n: int, timeout_s: float) -> GyroBlock: ...
    def close(self) -> None: ...


@runtime_checkable
class ConfigurableGyro(Protocol):
    """A gyro that states its own configuration when asked (a STIM300's ``C<CR>``).

    ``confirm_configuration`` asks, waits a bounded time, and raises the
    driver's protocol fault when the answer contradicts the station; a unit
    that does not answer is no fault (the answer says so). ``let_pass`` is
    called once after the question with the stream time to wait (a
    simulated clock lets it pass there). The answer is kept in ``configuration``, also
    when it raised.
    """

    #: the last answer (None: not asked yet)
    configuration: ConfigurationAnswer | None

    def confirm_configuration(self, timeout_s: float | None = None,
                              let_pass: Callable[[float], None] | None = None
                              ) -> ConfigurationAnswer: ...


@runtime_checkable
class IdentifyingGyro(Protocol):
    """A gyro that says who it is when asked (a STIM300's ``N<CR>``, ``I<CR>``) and when it
    starts (its start-up datagrams).

    ``ask_identity`` asks with the same bounded wait as ``confirm_configuration``;
    no answer is no fault. Its serial then stands in the identity description
    (``serial …``). ``take_start_up`` hands over what the unit sent when it
    started since the last call (None: nothing).
    """

    #: the last answer (None: not asked yet)
    unit_identity: IdentityAnswer | None

    def ask_identity(self, timeout_s: float | None = None,
                     let_pass: Callable[[float], None] | None = None) -> IdentityAnswer: ...
    def take_start_up(self) -> StartUpRecord | None: ...
