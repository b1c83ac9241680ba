"""The station file: which instruments a lab has, where they are, what they may do.

A procedure says *what* to measure; the station says *with what*. Keeping the
two apart lets one procedure run on several stations, and lets the station's
hard limits (what the chamber and table can safely do) bound every procedure
run on it. Identities and calibration due dates are recorded here because QA
needs them in the report, not because the orchestrator uses them.
"""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from gyrocal.inputs import load_yaml, outside_reference
from gyrocal.instruments.driver_spec import (
    DriverSpec,
    Role,
    Setting,
    SettingError,
    SettingKind,
    SettingValue,
)
from gyrocal.instruments.gyro.datagram_types import DEFAULT_ACCELEROMETER_RANGE_G, ID_RATE_TEMP
from gyrocal.instruments.registry import UnknownDriver, registry
from gyrocal.instruments.table.acutrol_protocol import DEFAULT_DIALECT
from gyrocal.models.drive_interference import DriveLine
from gyrocal.models.gravity import STANDARD_GRAVITY_MPS2, local_gravity_g
from gyrocal.models.gyro_model import ModelError
from gyrocal.models.imu_model import load_any_model
from gyrocal.orchestrator.notify import NotifyTarget, parse_notify
from gyrocal.problems import KeyPath, ProcedureError, sort_problems
from gyrocal.schema import (
    Context,
    Fields,
    boolean,
    choice,
    date,
    duration,
    file_name,
    integer,
    number,
    quantity,
    serial_number,
    text,
)
from gyrocal.units import (
    ACCELERATION,
    FREQUENCY,
    RATE,
    TEMPERATURE,
    TEMPERATURE_RATE,
    UnitError,
    format_number,
)

STATION_VERSION = 1
SIM_ADDRESS = "sim"   # "started by --sim": the simulator's loopback address is chosen at run time


@dataclass(frozen=True)
class Site:
    name: str
    latitude_deg: float   # sets the Earth-rate component the analysis removes
    address: str | None = None   # the lab's address, printed on the calibration certificate
    height_m: float = 0.0        # ellipsoidal height: local gravity (models/gravity.py)
    #: a measured local gravity (m/s²) replaces the normal-gravity formula, and its anomaly term
    gravity_mps2: float | None = None

    @property
    def gravity_g(self) -> float:
        """Local gravity in standard g: measured if declared, else WGS-84 normal gravity."""
        if self.gravity_mps2 is not None:
            return self.gravity_mps2 / STANDARD_GRAVITY_MPS2
        return local_gravity_g(self.latitude_deg, self.height_m)


#: ``uncertainty`` section keys: ± half-widths (rectangular) of the reference accuracies the
#: GUM budget uses as type B inputs (metrology/uncertainty.py states its defaults as assumed).
UNCERTAINTY_KEYS = ("table_rate_accuracy_ppm", "chamber_temp_accuracy_c",
                    "latitude_accuracy_deg", "axis_tilt_deg")


@dataclass(frozen=True)
class AssetIdentity:
    """An instrument as the lab's asset register knows it (for the QA report)."""

    make: str
    model: str
    serial: str
    calibration_due: dt.date | None
    #: why an overdue calibration may still give a PASS (shown in the report); None: it may not
    calibration_waiver: str | None = None
    #: the certificate of the instrument's own calibration, and who issued it: the link in the
    #: traceability chain the calibration certificate names (ISO/IEC 17025 §6.5, §7.8.4.1)
    calibration_certificate: str | None = None
    calibrated_by: str | None = None

    def calibration_overdue(self, on: dt.date) -> bool:
        return self.calibration_due is not None and on > self.calibration_due


@dataclass(frozen=True)
class ChamberLimits:
    min_temp_c: float
    max_temp_c: float
    max_ramp_c_per_min: float


@dataclass(frozen=True)
class ChamberSafeState:
    action: str                  # "setpoint" (hold setpoint_c) or "standby"
    setpoint_c: float | None


@dataclass(frozen=True)
class ChamberConfig:
    driver: str
    address: str
    unit_id: int
    identity: AssetIdentity
    limits: ChamberLimits
    safe_state: ChamberSafeState
    timeout_s: float
    retries: int
    #: Watlow F4: the digital input its limit controller is wired to (alarm source)
    limit_input: int | None = None
    #: Watlow F4 serial line (the F4's defaults: 9600 baud, no parity, 1 stop bit)
    baudrate: int = 9600
    parity: str = "N"
    stop_bits: int = 1
    #: Watlow F4T float word order (manual: low word first)
    word_order: str = "low_first"
    #: the driver's own settings, checked against its spec (instruments/registry.py)
    settings: Mapping[str, SettingValue] = field(default_factory=dict)


@dataclass(frozen=True)
class TableLimits:
    max_rate_dps: float
    max_accel_dps2: float


@dataclass(frozen=True)
class TableConfig:
    driver: str
    address: str
    axis: int
    identity: AssetIdentity
    limits: TableLimits
    timeout_s: float
    retries: int
    #: how the controller answers (instruments/table/acutrol_protocol.py DIALECTS: the manual's only)
    dialect: str = DEFAULT_DIALECT
    settings: Mapping[str, SettingValue] = field(default_factory=dict)
    #: "vertical" (a rate table) or "horizontal" (turned on its side: an indexing head that
    #: tilts the unit through gravity, for the tilt_linearity test)
    orientation: str = "vertical"

    @property
    def holds_axis_when_safe(self) -> bool:
        """A horizontal axis is held under servo in the safe state, never switched off: an
        unbalanced load on a servo-off horizontal axis swings down (safe_state.py)."""
        return self.orientation == "horizontal"


@dataclass(frozen=True)
class GyroConfig:
    driver: str
    port: str
    baudrate: int
    sample_rate_hz: float
    rate_lsb: float           # output units per LSB
    with_temperature: bool
    timeout_s: float
    axis: str = "x"           # unit under test among the datagram's x, y, z (all three are logged)
    crlf: bool = False        # datagrams terminated by CR LF (a STIM300 setting)
    #: the normal-mode datagram the unit is configured for (TS1524 Table 5-21); the driver
    #: checks it against the stream. Default: 0x94 with temperature, else 0x90.
    datagram: int = ID_RATE_TEMP
    #: accelerometer range, g (5, 10, 30 or 80; TS1524 §7.5.2.2.7): sets the LSB
    accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G
    settings: Mapping[str, SettingValue] = field(default_factory=dict)


#: what the safe state does with the unit's power (station supply.safe_state.unit_power)
UNIT_POWER_ACTIONS = ("keep_on", "switch_off")


@dataclass(frozen=True)
class SupplyConfig:
    """The programmable supply powering the unit under test."""

    driver: str
    address: str
    identity: AssetIdentity
    voltage_v: float
    current_limit_a: float
    #: "keep_on": a fault leaves the unit powered (its thermal state kept); "switch_off": off
    unit_power_safe: str
    timeout_s: float
    retries: int
    settings: Mapping[str, SettingValue] = field(default_factory=dict)


#: the table axis: vertical (a rate table) or horizontal (an indexing head through gravity)
TABLE_ORIENTATIONS = ("vertical", "horizontal")


@dataclass(frozen=True)
class InclinometerSim:
    """The simulated unit's inclinometers (station simulation.inclinometer): the x channel
    reads scale·a_x + quadratic·a_x² + bias, the y channel cross_axis·a_x, each + noise (g)."""

    scale: float = 1.0
    bias_g: float = 0.0
    quadratic_per_g: float = 0.0
    cross_axis: float = 0.0
    noise_g: float = 0.0


#: the coil's axis relative to the gyro: along its input (sensitive) axis, or across it
COIL_AXES = ("input", "transverse")


@dataclass(frozen=True)
class CoilConfig:
    """A Helmholtz coil driven by two channels of the station's supply (magnetic step kind).

    A programmable supply is unipolar, so the coil has its two polarities on two
    channels wired in opposition: ``positive_channel`` drives +B along ``axis``,
    ``negative_channel`` -B. Each channel runs in constant current (its voltage
    ``compliance_v`` above what the coil needs), so the field is the coil constant ×
    the channel's current, read back on both channels.
    """

    constant_t_per_a: float
    #: relative standard uncertainty of the coil constant (its calibration)
    u_constant_rel: float
    axis: str                 # COIL_AXES
    positive_channel: int
    negative_channel: int
    compliance_v: float
    max_current_a: float

    @property
    def max_field_t(self) -> float:
        return self.constant_t_per_a * self.max_current_a


@dataclass(frozen=True)
class ChamberPhysics:
    ambient_c: float
    tau_s: float
    max_heat_c_per_min: float
    max_cool_c_per_min: float
    noise_c: float


@dataclass(frozen=True)
class TablePhysics:
    rate_noise_dps: float
    #: what the powered drive adds to the gyro at rest (models/drive_interference.py)
    drive_lines: tuple[DriveLine, ...] = ()
    drive_noise_dph: float = 0.0


@dataclass(frozen=True)
class SimulationConfig:
    """What ``--sim`` and ``gyrocal sim serve`` start; ignored on real hardware."""

    gyro_model: Path          # resolved against the file that named it; must exist
    seed: int
    chamber: ChamberPhysics
    table: TablePhysics
    inclinometer: InclinometerSim = InclinometerSim()
    #: the simulated unit's start-up delay from the supply's output-on to its first frame;
    #: None: the unit ignores the supply (sends from the start, as before supplies existed)
    gyro_startup_s: float | None = None
    #: with it: 1 σ of a bias offset drawn afresh at each power-on (turn-on repeatability), deg/h
    turn_on_bias_dph: float = 0.0


@dataclass(frozen=True)
class Station:
    version: int
    name: str
    site: Site
    chamber: ChamberConfig
    table: TableConfig
    gyro: GyroConfig
    simulation: SimulationConfig | None
    file: str                 # as given (for messages); "<inline in ...>" when inline
    path: Path | None         # resolved file, None when written inline in a procedure
    #: the station's Ed25519 private key (gyrocal keys), resolved against the station file;
    #: runs are sealed with it (record/signing.py). None: unsigned unless
    #: --signing-key or $GYROCAL_SIGNING_KEY names one.
    signing_key: Path | None = None
    #: who is told when the run finishes, faults, pauses or needs a person (notify.py)
    notify: tuple[NotifyTarget, ...] = ()
    #: declared type B accuracies (UNCERTAINTY_KEYS); only the keys the file gives
    uncertainty: dict[str, float] | None = None
    #: the supply powering the unit under test; None: the unit is powered by other means
    supply: SupplyConfig | None = None
    #: the Helmholtz coil on two further channels of that supply; None: no magnetic tests
    coil: CoilConfig | None = None

    def addresses(self) -> dict[str, str]:
        """``{"chamber.address": …, "gyro.port": …}``: every instrument's address, by station key."""
        found = {"chamber.address": self.chamber.address, "table.address": self.table.address,
                 "gyro.port": self.gyro.port}
        if self.supply is not None:
            found["supply.address"] = self.supply.address
        return found

    @property
    def simulated(self) -> bool:
        """True when any instrument address is ``sim`` (started by ``--sim``)."""
        return SIM_ADDRESS in self.addresses().values()

    def limit_source(self, key: str) -> str:
        """``stations/sim.yaml table.limits.max_rate_dps``: where a limit came from, for messages."""
        return f"{self.file} {key}"


def load_station(path: str | os.PathLike[str], *, allow_outside: bool = False) -> Station:
    """Read and validate a station file; :class:`ProcedureError` lists every problem."""
    document = load_yaml(path)
    ctx = Context(document, allow_outside=allow_outside)
    station = parse_station(ctx, (), document.data, base_dir=document.path.parent,
                            file=document.file, path=document.path)
    if ctx.problems:
        raise ProcedureError(sort_problems(ctx.problems))
    assert station is not None
    return station


def parse_station(
    ctx: Context, where: KeyPath, value: object, *, base_dir: Path, file: str, path: Path | None
) -> Station | None:
    """Parse a station mapping (a whole file, or inline in a procedure at ``where``)."""
    fields = Fields(ctx, where, value, "a station")
    if not fields.valid:
        return None
    version = fields.take("version", integer())
    if version is not None and version != STATION_VERSION:
        ctx.report(fields.child("version"), f"unsupported station version {version}; "
                   f"this gyrocal reads version {STATION_VERSION}")
    name = fields.take("name", text)
    site = _site(ctx, fields)
    chamber = _chamber(ctx, fields)
    table = _table(ctx, fields)
    gyro = _gyro(ctx, fields)
    supply = _supply(ctx, fields) if fields.raw("supply")[0] else None
    present, raw = fields.raw("simulation")
    simulation = _simulation(ctx, fields.child("simulation"), raw, base_dir) if present else None
    key_text = fields.take("signing_key", file_name, required=False)
    signing_key = (base_dir / key_text) if key_text else None
    present, raw = fields.raw("notify")
    notify = parse_notify(ctx.report, fields.child("notify"), raw) if present else ()
    uncertainty = _uncertainty(ctx, fields)
    coil = _coil(ctx, fields, supply) if fields.raw("coil")[0] else None
    fields.finish()
    if simulation is None and SIM_ADDRESS in (
        getattr(chamber, "address", None), getattr(table, "address", None),
        getattr(gyro, "port", None), getattr(supply, "address", None),
    ):
        ctx.report(where, "an instrument address is 'sim' but there is no simulation section")
    return Station(version, name, site, chamber, table, gyro, simulation, file, path, signing_key,
                   notify, uncertainty, supply, coil)


def _coil(ctx: Context, parent: Fields, supply: SupplyConfig | None) -> CoilConfig | None:
    """The coil section; its channels must be free channels of the station's supply."""
    fields = _section(ctx, parent, "coil")
    constant = fields.take("constant_t_per_a", number(above=0.0, maximum=1.0, unit="T/A"))
    u_rel = fields.take("u_constant_rel", number(0.0, 0.5), required=False, default=0.0)
    axis = fields.take("axis", choice(COIL_AXES))
    channels = [fields.take(key, integer(1, 3)) for key in ("positive_channel", "negative_channel")]
    compliance_v = fields.take("compliance_v", number(above=0.0, maximum=100.0, unit="V"))
    max_current_a = fields.take("max_current_a", number(above=0.0, maximum=100.0, unit="A"))
    if supply is None:
        ctx.report(fields.child("positive_channel"), "the coil is driven by the station's supply, "
                   "but the station has no supply section")
    else:
        unit_channel = supply.settings.get("channel", 1)
        for key, channel in zip(("positive_channel", "negative_channel"), channels, strict=True):
            if channel is not None and channel == unit_channel:
                ctx.report(fields.child(key), f"channel {channel} powers the unit under test "
                           "(supply.channel); the coil needs channels of its own")
    if None not in channels and channels[0] == channels[1]:
        ctx.report(fields.child("negative_channel"), "must differ from positive_channel (the two "
                   "polarities are two channels wired in opposition)")
    fields.finish()
    if None in (constant, axis, compliance_v, max_current_a, *channels):
        return None
    return CoilConfig(constant, u_rel, axis, channels[0], channels[1], compliance_v, max_current_a)


def _uncertainty(ctx: Context, parent: Fields) -> dict[str, float] | None:
    present, raw = parent.raw("uncertainty")
    if not present:
        return None
    fields = Fields(ctx, parent.child("uncertainty"), raw, "uncertainty")
    declared = {key: fields.take(key, number(0.0, None), required=False)
                for key in UNCERTAINTY_KEYS}
    fields.finish()
    return {k: v for k, v in declared.items() if v is not None}


def _drive_lines(ctx: Context, parent: Fields) -> tuple[DriveLine, ...]:
    """``simulation.table.drive_lines``: [{frequency_hz, amplitude_dph}, …]."""
    present, raw = parent.raw("drive_lines")
    if not present:
        return ()
    if not isinstance(raw, list):
        ctx.report(parent.child("drive_lines"), "must be a list of {frequency_hz, amplitude_dph}")
        return ()
    lines = []
    for index, item in enumerate(raw):
        fields = Fields(ctx, (*parent.child("drive_lines"), index), item, "a drive line")
        if not fields.valid:
            continue
        frequency = fields.take("frequency_hz", number(0.0))
        amplitude = fields.take("amplitude_dph", number(0.0))
        fields.finish()
        if frequency is not None and amplitude is not None:
            lines.append(DriveLine(frequency, amplitude))
    return tuple(lines)


def _site(ctx: Context, parent: Fields) -> Site:
    fields = _section(ctx, parent, "site")
    site = Site(fields.take("name", text), fields.take("latitude_deg", number(-90.0, 90.0)),
                fields.take("address", text, required=False),
                fields.take("height_m", number(-500.0, 9000.0), required=False, default=0.0),
                fields.take("gravity_mps2", number(9.7, 9.9), required=False))
    fields.finish()
    return site


def _section(ctx: Context, parent: Fields, key: str) -> Fields:
    present, raw = parent.raw(key)
    if not present:
        if parent.valid:
            ctx.report(parent.child(key), "required key is missing")
        return Fields(ctx, parent.child(key), {}, key)
    return Fields(ctx, parent.child(key), raw, key)


def _driver(role: Role) -> object:
    def convert(value: object) -> DriverSpec:
        try:
            return registry().get(role, text(value))
        except UnknownDriver as exc:
            raise UnitError(str(exc)) from None
    return convert


def _address(spec: DriverSpec | None) -> object:
    def convert(value: object) -> str:
        address = text(value)
        if address == SIM_ADDRESS or spec is None or spec.address.matches(address):
            return address
        raise UnitError(f"{address!r} is not an address for {spec.name}; expected "
                        f"{spec.address.expected} or '{SIM_ADDRESS}'")
    return convert


def _setting(setting: Setting) -> object:
    """The schema's own converter for the setting's kind (same messages as every other key)."""
    if setting.kind is SettingKind.INTEGER and setting.parse is None:
        return integer(_whole(setting.minimum), _whole(setting.maximum))
    if setting.kind is SettingKind.NUMBER and setting.parse is None:
        return number(setting.minimum, setting.maximum, above=setting.above, unit=setting.unit)
    if setting.kind is SettingKind.BOOLEAN:
        return boolean
    if setting.kind is SettingKind.TEXT:
        return text
    if setting.kind is SettingKind.CHOICE and all(isinstance(c, str) for c in setting.choices):
        return choice(tuple(str(c) for c in setting.choices))

    def convert(value: object) -> SettingValue:
        try:
            return setting.convert(value)
        except SettingError as exc:
            raise UnitError(str(exc)) from None
    return convert


def _whole(limit: float | None) -> int | None:
    return None if limit is None else int(limit)


def _driver_settings(ctx: Context, fields: Fields, role: Role,
                     spec: DriverSpec | None) -> dict[str, SettingValue]:
    """The settings ``spec`` takes, checked against its schema; another driver's key is refused."""
    owners: dict[str, list[str]] = {}
    for other in registry().for_role(role):
        for setting in other.settings:
            owners.setdefault(setting.name, []).append(other.name)
    values: dict[str, SettingValue] = {}
    if spec is not None:
        for setting in spec.settings:
            values[setting.name] = fields.take(setting.name, _setting(setting),
                                               required=setting.required, default=setting.default)
        if spec.check is not None:
            values, problems = spec.check(values)
            for key, message in problems:
                ctx.report(fields.child(key), message)
    for name, drivers in owners.items():
        fields.used.add(name)   # every driver's keys are known here; another driver's is refused
        if fields.has(name) and (spec is None or spec.setting(name) is None):
            fields.take(name, lambda v: v, required=False)
            if spec is not None:
                ctx.report(fields.child(name), f"applies to driver {' or '.join(drivers)} only")
    return values


def _identity(ctx: Context, parent: Fields) -> AssetIdentity:
    fields = _section(ctx, parent, "identity")
    identity = AssetIdentity(
        fields.take("make", text),
        fields.take("model", text),
        fields.take("serial", serial_number),
        fields.take("calibration_due", date, required=False),
        fields.take("calibration_waiver", text, required=False),
        fields.take("calibration_certificate", serial_number, required=False),
        fields.take("calibrated_by", text, required=False),
    )
    fields.finish()
    return identity


def _common_link(fields: Fields) -> tuple[float, int]:
    timeout_s = fields.take("timeout_s", duration(bare_seconds=True), required=False, default=1.0)
    retries = fields.take("retries", integer(0, 20), required=False, default=3)
    return timeout_s, retries


def _chamber(ctx: Context, parent: Fields) -> ChamberConfig:
    fields = _section(ctx, parent, "chamber")
    spec = fields.take("driver", _driver(Role.CHAMBER))
    address = fields.take("address", _address(spec))
    settings = _driver_settings(ctx, fields, Role.CHAMBER, spec)
    identity = _identity(ctx, fields)

    lim = _section(ctx, fields, "limits")
    limits = ChamberLimits(
        lim.take("min_temp_c", quantity(TEMPERATURE, -273.15)),
        lim.take("max_temp_c", quantity(TEMPERATURE, -273.15)),
        lim.take("max_ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0)),
    )
    lim.finish()
    if None not in (limits.min_temp_c, limits.max_temp_c) and limits.min_temp_c >= limits.max_temp_c:
        ctx.report(lim.child("max_temp_c"),
                   f"max_temp_c {format_number(limits.max_temp_c)} °C must be above "
                   f"min_temp_c {format_number(limits.min_temp_c)} °C")

    safe = _section(ctx, fields, "safe_state")
    action = safe.take("action", choice(("setpoint", "standby")))
    setpoint_c = safe.take("setpoint_c", quantity(TEMPERATURE), required=action == "setpoint")
    if action == "standby" and safe.has("setpoint_c"):
        ctx.report(safe.child("setpoint_c"), "setpoint_c applies only to action: setpoint")
    if setpoint_c is not None and None not in (limits.min_temp_c, limits.max_temp_c) and not (
        limits.min_temp_c <= setpoint_c <= limits.max_temp_c
    ):
        ctx.report(safe.child("setpoint_c"),
                   f"{format_number(setpoint_c)} °C is outside the chamber limits "
                   f"{format_number(limits.min_temp_c)}…{format_number(limits.max_temp_c)} °C")
    safe.finish()
    timeout_s, retries = _common_link(fields)
    fields.finish()
    typed = _Typed(settings)
    return ChamberConfig(spec.name if spec else None, address, typed.get("unit_id", 1), identity,
                         limits, ChamberSafeState(action, setpoint_c), timeout_s, retries,
                         typed.get("limit_input", None), typed.get("baudrate", 9600),
                         typed.get("parity", "N"), typed.get("stop_bits", 1),
                         typed.get("word_order", "low_first"), settings)


def _supply(ctx: Context, parent: Fields) -> SupplyConfig:
    fields = _section(ctx, parent, "supply")
    spec = fields.take("driver", _driver(Role.SUPPLY))
    address = fields.take("address", _address(spec))
    settings = _driver_settings(ctx, fields, Role.SUPPLY, spec)
    identity = _identity(ctx, fields)
    voltage_v = fields.take("voltage_v", number(0.0, None, unit="V"))
    current_limit_a = fields.take("current_limit_a", number(above=0.0, unit="A"))
    safe = _section(ctx, fields, "safe_state")
    unit_power = safe.take("unit_power", choice(UNIT_POWER_ACTIONS))
    safe.finish()
    timeout_s, retries = _common_link(fields)
    fields.finish()
    return SupplyConfig(spec.name if spec else None, address, identity, voltage_v,
                        current_limit_a, unit_power, timeout_s, retries, settings)


def _table(ctx: Context, parent: Fields) -> TableConfig:
    fields = _section(ctx, parent, "table")
    spec = fields.take("driver", _driver(Role.TABLE))
    address = fields.take("address", _address(spec))
    settings = _driver_settings(ctx, fields, Role.TABLE, spec)
    identity = _identity(ctx, fields)
    lim = _section(ctx, fields, "limits")
    limits = TableLimits(
        lim.take("max_rate_dps", quantity(RATE, above=0.0)),
        lim.take("max_accel_dps2", quantity(ACCELERATION, above=0.0)),
    )
    lim.finish()
    orientation = fields.take("orientation", choice(TABLE_ORIENTATIONS), required=False,
                              default="vertical")
    timeout_s, retries = _common_link(fields)
    fields.finish()
    typed = _Typed(settings)
    return TableConfig(spec.name if spec else None, address, typed.get("axis", 1), identity,
                       limits, timeout_s, retries, typed.get("dialect", DEFAULT_DIALECT), settings,
                       orientation)


def _gyro(ctx: Context, parent: Fields) -> GyroConfig:
    fields = _section(ctx, parent, "gyro")
    spec = fields.take("driver", _driver(Role.GYRO))
    port = fields.take("port", _address(spec))
    sample_rate_hz = fields.take("sample_rate_hz", quantity(FREQUENCY, above=0.0))
    timeout_s = fields.take("timeout_s", duration(bare_seconds=True), required=False, default=2.0)
    settings = _driver_settings(ctx, fields, Role.GYRO, spec)
    fields.finish()
    typed = _Typed(settings)
    return GyroConfig(spec.name if spec else None, port, typed.get("baudrate", 0), sample_rate_hz,
                      typed.get("rate_lsb", 1.0), typed.get("with_temperature", False), timeout_s,
                      typed.get("axis", "x"), typed.get("crlf", False),
                      typed.get("datagram", ID_RATE_TEMP),
                      typed.get("accelerometer_range_g", DEFAULT_ACCELEROMETER_RANGE_G), settings)


class _Typed:
    """A driver's settings read into the station's typed fields (a default where it has none)."""

    def __init__(self, settings: Mapping[str, SettingValue]) -> None:
        self.settings = settings

    def get(self, name: str, default):
        value = self.settings.get(name)
        return default if value is None else value


def _check_model_file(ctx: Context, where: KeyPath, path: Path) -> None:
    """The model a dry run would simulate, read now: ``validate`` OK must mean ``run --sim`` accepts.

    The model's own error (file, line, key) is kept whole after the station's key.
    """

    try:
        load_any_model(path)
    except (ModelError, OSError, ValueError) as exc:
        ctx.report(where, f"the gyro model file is not usable: {exc}")


def _simulation(ctx: Context, where: KeyPath, value: object, base_dir: Path) -> SimulationConfig:
    fields = Fields(ctx, where, value, "simulation")
    model_text = fields.take("gyro_model", file_name)
    gyro_model = (base_dir / model_text).resolve() if model_text is not None else None
    refused = None if gyro_model is None or ctx.allow_outside else outside_reference(
        ctx.document.path, gyro_model)
    if refused is not None:
        ctx.report(fields.child("gyro_model"), refused)
        gyro_model = None
    elif gyro_model is not None and not gyro_model.is_file():
        ctx.report(fields.child("gyro_model"), f"gyro model file not found: {gyro_model} "
                   "(the path is relative to the file that names it)")
    elif gyro_model is not None:
        _check_model_file(ctx, fields.child("gyro_model"), gyro_model)
    seed = fields.take("seed", integer(0), required=False, default=1)

    ch = _section(ctx, fields, "chamber")
    chamber = ChamberPhysics(
        ch.take("ambient_c", quantity(TEMPERATURE, -273.15, 1000.0)),
        ch.take("tau_s", duration(bare_seconds=True)),
        ch.take("max_heat_c_per_min", quantity(TEMPERATURE_RATE, above=0.0)),
        ch.take("max_cool_c_per_min", quantity(TEMPERATURE_RATE, above=0.0)),
        ch.take("noise_c", number(0.0, unit="°C"), required=False, default=0.0),
    )
    ch.finish()
    tb = _section(ctx, fields, "table")
    table = TablePhysics(tb.take("rate_noise_dps", quantity(RATE, 0.0), required=False, default=0.0),
                         _drive_lines(ctx, tb),
                         tb.take("drive_noise_dph", number(0.0), required=False, default=0.0))
    tb.finish()
    inclinometer = _inclinometer_sim(ctx, fields) if fields.raw("inclinometer")[0] \
        else InclinometerSim()
    startup_s = fields.take("gyro_startup_s", number(0.0, 60.0, unit="s"), required=False,
                            default=None)
    turn_on_bias = fields.take("turn_on_bias_dph", number(0.0, 1e4, unit="deg/h"), required=False,
                               default=0.0)
    fields.finish()
    return SimulationConfig(gyro_model, seed, chamber, table, inclinometer, startup_s,
                            turn_on_bias)


def _inclinometer_sim(ctx: Context, parent: Fields) -> InclinometerSim:
    fields = _section(ctx, parent, "inclinometer")
    values = InclinometerSim(
        fields.take("scale", number(0.5, 2.0), required=False, default=1.0),
        fields.take("bias_g", number(-0.1, 0.1, unit="g"), required=False, default=0.0),
        fields.take("quadratic_per_g", number(-0.1, 0.1), required=False, default=0.0),
        fields.take("cross_axis", number(-0.5, 0.5), required=False, default=0.0),
        fields.take("noise_g", number(0.0, 0.1, unit="g"), required=False, default=0.0),
    )
    fields.finish()
    return values
