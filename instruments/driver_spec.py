"""What a driver is to gyrocal: one :class:`DriverSpec` per instrument model.

A spec says everything the rest of the program needs to know about a driver —
its name in station files, its role, the settings it takes (with defaults and
units), how its address looks, how to build it from those settings, how to
start its simulator, and which documents it follows — so that station
loading, the factory, the simulated station and the docs never list drivers
themselves. Built-in drivers are specs in ``builtin_drivers.py``; a third-party
package publishes its own through the ``gyrocal.drivers`` entry-point group
(``registry.py``), needing nothing inside gyrocal changed.

This module holds only types, so a plug-in can import it without pulling in
any driver.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

from gyrocal.instruments.errors import InstrumentError
from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import Clock
from gyrocal.models.table import TablePhysics

#: a setting's value once checked against its :class:`Setting`
SettingValue = int | float | str | bool | None
Settings = Mapping[str, SettingValue]


class Role(str, enum.Enum):
    """What an instrument does on the station (the station file's section name)."""

    CHAMBER = "chamber"
    TABLE = "table"
    GYRO = "gyro"
    SUPPLY = "supply"
    DMM = "dmm"
    COUNTER = "counter"


class SettingKind(enum.Enum):
    INTEGER = "integer"
    NUMBER = "number"
    TEXT = "text"
    BOOLEAN = "boolean"
    CHOICE = "choice"


class SettingError(ValueError):
    """A setting's value is not what its schema allows (the message names what is)."""


@dataclass(frozen=True)
class Setting:
    """One key a driver takes in its station section: its type, default, unit and limits."""

    name: str
    kind: SettingKind
    default: SettingValue = None
    unit: str = ""
    doc: str = ""
    minimum: float | None = None
    maximum: float | None = None
    above: float | None = None       # exclusive minimum (a value must exceed it)
    choices: tuple[SettingValue, ...] = ()
    required: bool = False
    #: the default as the reference shows it, when it is not a plain value ("from `datagram`")
    default_text: str = ""
    #: a converter of its own for values no kind describes (e.g. ``0x94``); raises ValueError
    parse: Callable[[object], SettingValue] | None = None

    def convert(self, value: object) -> SettingValue:
        """``value`` as this setting's type, or :class:`SettingError` saying what was expected."""
        if self.parse is not None:
            try:
                return self.parse(value)
            except ValueError as exc:
                raise SettingError(str(exc)) from None
        if self.kind is SettingKind.CHOICE:
            if isinstance(value, bool) or value not in self.choices:
                raise SettingError("expected one of " + ", ".join(str(c) for c in self.choices)
                                   + f", got {value!r}")
            return value  # type: ignore[return-value]
        if self.kind is SettingKind.BOOLEAN:
            if not isinstance(value, bool):
                raise SettingError(f"expected true or false, got {value!r}")
            return value
        if self.kind is SettingKind.TEXT:
            if not isinstance(value, str) or not value.strip():
                raise SettingError(f"expected text, got {value!r}")
            return value
        return self._number(value)

    def _number(self, value: object) -> int | float:
        whole = self.kind is SettingKind.INTEGER
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                whole and not isinstance(value, int)):
            raise SettingError(f"expected {'a whole number' if whole else 'a number'}"
                               f"{' in ' + self.unit if self.unit else ''}, got {value!r}")
        unit = f" {self.unit}" if self.unit else ""
        if self.above is not None and not value > self.above:
            raise SettingError(f"{value}{unit} must be above {self.above:g}{unit}")
        if self.minimum is not None and value < self.minimum:
            raise SettingError(f"{value}{unit} is below the minimum {self.minimum:g}{unit}")
        if self.maximum is not None and value > self.maximum:
            raise SettingError(f"{value}{unit} is above the maximum {self.maximum:g}{unit}")
        return int(value) if whole else float(value)

    def describe(self) -> str:
        """``baudrate (integer, default 9600): …`` for docs and messages."""
        kind = "one of " + "/".join(str(c) for c in self.choices) if self.choices else self.kind.value
        unit = f", {self.unit}" if self.unit else ""
        default = f", default {self.default}" if self.default is not None else ""
        return f"{self.name} ({kind}{unit}{default}){': ' + self.doc if self.doc else ''}"


@dataclass(frozen=True)
class AddressForm:
    """What an address for the driver looks like (``sim`` is always accepted besides)."""

    pattern: str
    expected: str     # said in the message when an address does not match

    def matches(self, address: str) -> bool:
        return re.match(self.pattern, address) is not None


HOST_PORT = r"[A-Za-z0-9_.\-]+:\d{1,5}"
SERIAL_OR_SOCKET = AddressForm(rf"^(/dev/\S+|COM\d+|socket://{HOST_PORT})$",
                               "a serial device (/dev/ttyUSB0, COM3) or socket://host:port")
TCP_HOST_PORT = AddressForm(rf"^{HOST_PORT}$", "host:port")
VISA_RESOURCE = AddressForm(r"^(TCPIP\d*::\S+|ASRL\S+|GPIB\d*::\S+|USB\d*::\S+)$",
                            "a VISA resource such as TCPIP0::10.0.0.5::5025::SOCKET")


@dataclass(frozen=True)
class OpenRequest:
    """What a driver is built from: the station's address and settings for it."""

    address: str
    timeout_s: float
    retries: int
    settings: Settings
    #: called with (attempt, error) for every retried exchange (journaled by the run)
    on_retry: Callable[[int, InstrumentError], None] | None = None
    #: the gyro's configured output rate, when the run's differs from the station file's
    sample_rate_hz: float | None = None
    clock: Clock | None = None


class SimServer(Protocol):
    """A simulator the simulated station starts: a real server with an address to reach."""

    @property
    def address(self) -> str: ...
    def start(self) -> object: ...
    def stop(self) -> None: ...
    def reseed(self, seed: object) -> None:
        """Draw from ``seed`` (a numpy SeedSequence) from here: one per run attempt."""


class FaultArming(Protocol):
    """The simulator's armed faults (instruments/sim/faults.py FaultInjector)."""

    def arm(self, name: str, count: int | None = 1, **params: object) -> None: ...
    def take(self, name: str) -> dict[str, object] | None: ...
    def is_armed(self, name: str) -> bool: ...


@dataclass(frozen=True)
class SimRequest:
    """What a simulator gets from the simulated station: its settings, faults and the shared physics.

    Every simulator sees the same bench, so a chamber's air temperature, the
    table's rate and the gyro model's output agree across instruments.
    """

    settings: Settings
    faults: FaultArming
    clock: Clock
    seed: int
    chamber: ChamberPhysics | None = None
    table: TablePhysics | None = None
    #: the gyro model's output at given times: (t_s array) -> (output array, sensor temperature array)
    gyro_source: Callable | None = None
    sample_rate_hz: float | None = None
    #: a three-axis IMU's specific force at given times (its accelerometers), else None
    specific_force: Callable | None = None
    #: the serial the simulated unit reports (the procedure's unit under test), if any
    unit_serial: str | None = None


#: a spec's cross-field rule: the settings as given (None where absent) -> the settings to use
#: (derived values filled in) and [(setting name, problem)]
SettingsCheck = Callable[[dict[str, SettingValue]],
                         tuple[dict[str, SettingValue], list[tuple[str, str]]]]


@dataclass(frozen=True)
class DriverSpec:
    """Everything about one driver, in one place."""

    name: str                          # the station file's ``driver:`` value
    role: Role
    summary: str                       # one line: make, model, link
    address: AddressForm
    open: Callable[[OpenRequest], object]
    settings: tuple[Setting, ...] = ()
    #: builds the simulator, or None when the driver has none (then --sim cannot use it)
    simulator: Callable[[SimRequest], SimServer] | None = None
    #: the names ``--inject ROLE.FAULT`` accepts for its simulator
    sim_faults: tuple[str, ...] = ()
    #: the manuals and sources it follows (manual + section), for docs and the manifest
    documents: tuple[str, ...] = ()
    check: SettingsCheck | None = None
    #: where the spec came from: "gyrocal" or the distribution that published it
    origin: str = field(default="gyrocal", compare=False)

    def setting(self, name: str) -> Setting | None:
        return next((s for s in self.settings if s.name == name), None)

    def defaults(self) -> dict[str, SettingValue]:
        return {s.name: s.default for s in self.settings}
