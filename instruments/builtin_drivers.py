"""The drivers that ship with gyrocal, each as one :class:`DriverSpec`.

Adding a driver to gyrocal itself is one spec here; adding one from outside
is the same spec published through the ``gyrocal.drivers`` entry point
(README "Add your instrument"). Each spec names its driver and simulator
classes directly, so the layer check (tests/test_layout.py) sees every import.
"""

from __future__ import annotations

import time

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4
from gyrocal.instruments.chamber.watlow_f4t import WatlowF4T
from gyrocal.instruments.driver_spec import (
    SERIAL_OR_SOCKET,
    TCP_HOST_PORT,
    VISA_RESOURCE,
    AddressForm,
    DriverSpec,
    OpenRequest,
    Role,
    Setting,
    SettingKind,
    SettingValue,
    SimRequest,
)
from gyrocal.instruments.gyro.datagram import axis_index
from gyrocal.instruments.gyro.datagram_types import (
    ACCELEROMETER_LSB_G,
    DEFAULT_ACCELEROMETER_RANGE_G,
    ID_RATE,
    ID_RATE_TEMP,
    NORMAL_MODE_TYPES,
    datagram_type,
    parse_identifier,
)
from gyrocal.instruments.gyro.pulse_counter import CounterPulseGyro
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.gyro.truevolt import TruevoltAnalogGyro
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.chamber_server import FAULTS as CHAMBER_FAULTS
from gyrocal.instruments.sim.chamber_server import SimulatedWatlowF4, SimulatedWatlowF4T
from gyrocal.instruments.sim.counter_server import FAULTS as COUNTER_FAULTS
from gyrocal.instruments.sim.counter_server import SimulatedCounter
from gyrocal.instruments.sim.gyro_pty import FAULTS as GYRO_FAULTS
from gyrocal.instruments.sim.gyro_pty import SimulatedGyroPort
from gyrocal.instruments.sim.supply_server import FAULTS as SUPPLY_FAULTS
from gyrocal.instruments.sim.supply_server import SimulatedE36300
from gyrocal.instruments.sim.table_server import FAULTS as TABLE_FAULTS
from gyrocal.instruments.sim.table_server import SimulatedAcutrol
from gyrocal.instruments.sim.truevolt_server import FAULTS as DMM_FAULTS
from gyrocal.instruments.sim.truevolt_server import SimulatedTruevolt
from gyrocal.instruments.supply.keysight_e36300 import KeysightE36300Supply
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.instruments.table.acutrol_protocol import DEFAULT_DIALECT, DIALECTS

#: Over ``socket://`` the RTU bytes cross TCP and no UART paces them; the baud rate
#: would only make pymodbus wait for imaginary character times (36 ms a read at 9600).
_SOCKET_BAUD = 921600

_ACUTROL_ADDRESS = AddressForm(VISA_RESOURCE.pattern,
                               "a VISA resource such as TCPIP0::10.0.0.5::9878::SOCKET")
_UNIT_ID = Setting("unit_id", SettingKind.INTEGER, 1, doc="Modbus unit (slave) id",
                   minimum=1, maximum=247)


def _int(settings, name: str) -> int:
    value = settings[name]
    assert isinstance(value, int)
    return value


def _open_f4(req: OpenRequest):
    s = req.settings
    baud = _SOCKET_BAUD if req.address.startswith("socket://") else _int(s, "baudrate")
    limit_input = s["limit_input"]
    return WatlowF4(req.address, unit_id=_int(s, "unit_id"), timeout_s=req.timeout_s,
                    retry=RetryPolicy(attempts=req.retries), baudrate=baud, parity=str(s["parity"]),
                    stop_bits=_int(s, "stop_bits"),
                    limit_input=limit_input if isinstance(limit_input, int) else None,
                    on_retry=req.on_retry)


def _sim_f4(req: SimRequest):
    assert req.chamber is not None
    return SimulatedWatlowF4(req.chamber, req.faults, unit_id=_int(req.settings, "unit_id"))


def _open_f4t(req: OpenRequest):
    s = req.settings
    return WatlowF4T(req.address, unit_id=_int(s, "unit_id"), timeout_s=req.timeout_s,
                     retry=RetryPolicy(attempts=req.retries), word_order=str(s["word_order"]),
                     on_retry=req.on_retry)


def _sim_f4t(req: SimRequest):
    assert req.chamber is not None
    return SimulatedWatlowF4T(req.chamber, req.faults, unit_id=_int(req.settings, "unit_id"))


def _open_acutrol(req: OpenRequest):
    s = req.settings
    return Acutrol3000Table(req.address, axis=_int(s, "axis"), timeout_s=req.timeout_s,
                            retry=RetryPolicy(attempts=req.retries), on_retry=req.on_retry,
                            dialect=str(s["dialect"]))


def _sim_acutrol(req: SimRequest):
    class _Served(SimulatedAcutrol):
        @property
        def address(self) -> str:
            return self.resource

    assert req.table is not None
    return _Served(req.table, req.faults, dialect=str(req.settings["dialect"]))


def _open_stim300(req: OpenRequest):
    s = req.settings
    rate_lsb = s["rate_lsb"]
    assert isinstance(rate_lsb, float) and req.sample_rate_hz is not None
    return Stim300Gyro(req.address, baudrate=_int(s, "baudrate"), sample_rate_hz=req.sample_rate_hz,
                       with_temperature=bool(s["with_temperature"]), lsb=rate_lsb,
                       timeout_s=req.timeout_s, axis=str(s["axis"]), crlf=bool(s["crlf"]),
                       datagram=_int(s, "datagram"),
                       accelerometer_range_g=_int(s, "accelerometer_range_g"),
                       transport_wait=time.sleep if req.clock is None else req.clock.transport_wait)


def _sim_stim300(req: SimRequest):
    class _Served(SimulatedGyroPort):
        @property
        def address(self) -> str:
            return self.port_name

    s = req.settings
    rate_lsb = s["rate_lsb"]
    assert req.gyro_source is not None and req.sample_rate_hz is not None
    assert isinstance(rate_lsb, float)
    block = s.get("_block_frames")
    return _Served(req.gyro_source, req.clock, sample_rate_hz=req.sample_rate_hz,  # type: ignore[arg-type]
                   with_temperature=bool(s["with_temperature"]), lsb=rate_lsb,
                   faults=req.faults, block_frames=block if isinstance(block, int) else 512,  # type: ignore[arg-type]
                   seed=req.seed, axis=axis_index(str(s["axis"])), crlf=bool(s["crlf"]),
                   datagram=_int(s, "datagram"),
                   accelerometer_range_g=_int(s, "accelerometer_range_g"),
                   specific_force=req.specific_force, baudrate=_int(s, "baudrate"),
                   unit_serial=req.unit_serial)


def _open_e36300(req: OpenRequest):
    return KeysightE36300Supply(req.address, channel=_int(req.settings, "channel"),
                                timeout_s=req.timeout_s, retry=RetryPolicy(attempts=req.retries),
                                on_retry=req.on_retry)


def _sim_e36300(req: SimRequest):
    return SimulatedE36300(req.faults, seed=req.seed, clock=req.clock)  # type: ignore[arg-type]


def _open_truevolt(req: OpenRequest):
    s = req.settings
    aperture, nplc = s.get("aperture_s"), s.get("nplc")
    assert req.sample_rate_hz is not None
    return TruevoltAnalogGyro(req.address, req.sample_rate_hz, range_v=float(s["range_v"]),  # type: ignore[arg-type]
                              aperture_s=float(aperture) if aperture is not None else None,  # type: ignore[arg-type]
                              nplc=float(nplc) if nplc is not None else None,  # type: ignore[arg-type]
                              timeout_s=req.timeout_s, retry=RetryPolicy(attempts=3),
                              on_retry=req.on_retry)


def _sim_truevolt(req: SimRequest):
    assert req.gyro_source is not None
    return SimulatedTruevolt(req.gyro_source, req.clock, req.faults)  # type: ignore[arg-type]


def _open_counter(req: OpenRequest):
    s = req.settings
    assert req.sample_rate_hz is not None
    return CounterPulseGyro(req.address, req.sample_rate_hz,
                            pulse_weight_arcsec=float(s["pulse_weight_arcsec"]),  # type: ignore[arg-type]
                            channel=_int(s, "channel"), timeout_s=req.timeout_s,
                            retry=RetryPolicy(attempts=3), on_retry=req.on_retry)


def _sim_counter(req: SimRequest):
    assert req.gyro_source is not None
    return SimulatedCounter(req.gyro_source, req.clock,
                            float(req.settings["pulse_weight_arcsec"]), req.faults)  # type: ignore[arg-type]


def _one_integration(given: dict[str, SettingValue]
                     ) -> tuple[dict[str, SettingValue], list[tuple[str, str]]]:
    if given.get("aperture_s") is not None and given.get("nplc") is not None:
        return given, [("nplc", "give aperture_s or nplc, not both")]
    return given, []


def _identifier(value: object) -> int:
    return parse_identifier(value)


def _settle_stim300(given: dict[str, SettingValue]
                    ) -> tuple[dict[str, SettingValue], list[tuple[str, str]]]:
    """The datagram follows ``with_temperature`` when not given; the two must agree when both are."""
    settled = dict(given)
    with_temperature, datagram = given.get("with_temperature"), given.get("datagram")
    problems: list[tuple[str, str]] = []
    if not isinstance(datagram, int):
        datagram = ID_RATE if with_temperature is False else ID_RATE_TEMP
    elif with_temperature is not None and with_temperature != datagram_type(datagram).temperature:
        problems.append(("with_temperature",
                         f"{str(with_temperature).lower()} contradicts datagram "
                         f"{datagram_type(datagram).label()}; give one of them"))
    settled["datagram"] = datagram
    settled["with_temperature"] = datagram_type(datagram).temperature
    return settled, problems


_WATLOW_F4_DOCS = ("Watlow Series F4 user's manual 'PID temperature Control f4pe E' (Modbus registers)",
                   "Espec ChamberConnectLibrary watlowf4.py (run state 200, units 901, decimals 606)")
_WATLOW_F4T_DOCS = ("Watlow F4T setup and operations guide 0600-0093-0000 (p. 225 display units)",
                    "Espec ChamberConnectLibrary watlowf4t.py")

BUILTIN_DRIVERS: tuple[DriverSpec, ...] = (
    DriverSpec(
        "watlow_f4", Role.CHAMBER, "Watlow Series F4, Modbus RTU (serial or serial-over-TCP)",
        SERIAL_OR_SOCKET, _open_f4,
        settings=(
            _UNIT_ID,
            Setting("limit_input", SettingKind.INTEGER, None, minimum=1, maximum=4,
                    doc="the digital input the limit controller trips (alarm source)"),
            Setting("baudrate", SettingKind.INTEGER, 9600, unit="baud", minimum=1200,
                    maximum=115_200, doc="serial speed"),
            Setting("parity", SettingKind.CHOICE, "N", choices=("N", "E", "O"), doc="serial parity"),
            Setting("stop_bits", SettingKind.INTEGER, 1, minimum=1, maximum=2,
                    doc="serial stop bits"),
        ),
        simulator=_sim_f4, sim_faults=CHAMBER_FAULTS, documents=_WATLOW_F4_DOCS),
    DriverSpec(
        "watlow_f4t", Role.CHAMBER, "Watlow F4T, Modbus TCP", TCP_HOST_PORT, _open_f4t,
        settings=(_UNIT_ID,
                  Setting("word_order", SettingKind.CHOICE, "low_first",
                          choices=("low_first", "high_first"), doc="float word order")),
        simulator=_sim_f4t, sim_faults=CHAMBER_FAULTS, documents=_WATLOW_F4T_DOCS),
    DriverSpec(
        "acutrol3000", Role.TABLE,
        "Acutronic ACUTROL3000, its command language over a raw TCP socket (TM-8004; port "
        "9878, TM-9384C §1)", _ACUTROL_ADDRESS, _open_acutrol,
        settings=(Setting("axis", SettingKind.INTEGER, 1, minimum=1, maximum=8,
                          doc="which axis of the controller"),
                  Setting("dialect", SettingKind.CHOICE, DEFAULT_DIALECT,
                          choices=tuple(DIALECTS), doc="how the controller answers")),
        simulator=_sim_acutrol, sim_faults=TABLE_FAULTS,
        documents=("ACUTROL3000 TM-8004 command language; TM-9384C TCP/IP",
                   "docs/protocol-elements.md (table rows)")),
    DriverSpec(
        "stim300", Role.GYRO, "Safran STIM300, RS-422 datagrams (serial or serial-over-TCP)",
        SERIAL_OR_SOCKET, _open_stim300,
        settings=(
            Setting("baudrate", SettingKind.INTEGER, 921600, unit="baud", minimum=1200,
                    maximum=20_000_000, doc="serial speed"),
            Setting("rate_lsb", SettingKind.NUMBER, None, required=True, above=0.0,
                    doc="output units per LSB of the datagram's rate field"),
            Setting("axis", SettingKind.CHOICE, "x", choices=("x", "y", "z"),
                    doc="which datagram axis is the unit under test (all three are logged)"),
            Setting("with_temperature", SettingKind.BOOLEAN, None,
                    doc="datagrams carry temperatures", default_text="from `datagram`, else true"),
            Setting("crlf", SettingKind.BOOLEAN, False,
                    doc="datagrams end in CR LF (a STIM300 setting)"),
            Setting("datagram", SettingKind.CHOICE, None, parse=_identifier,
                    choices=tuple(NORMAL_MODE_TYPES),
                    doc="the normal-mode datagram the unit is configured for (STIM300 datasheet "
                        "TS1524 Table 5-21), checked against the stream at connect; must agree "
                        "with `with_temperature` when both are given",
                    default_text=f"0x{ID_RATE_TEMP:02X} (0x{ID_RATE:02X} with "
                                 "`with_temperature: false`)"),
            Setting("accelerometer_range_g", SettingKind.CHOICE, DEFAULT_ACCELEROMETER_RANGE_G,
                    unit="g", choices=tuple(ACCELEROMETER_LSB_G),
                    doc="the unit's accelerometer range in g (sets the LSB when the datagram "
                        "carries acceleration)"),
        ),
        simulator=_sim_stim300, sim_faults=GYRO_FAULTS, check=_settle_stim300,
        documents=("STIM300 datasheet TS1524 rev 31 (Tables 5-16, 5-20..5-23, §7.5.2.2)",)),
    DriverSpec(
        "keysight_e36300", Role.SUPPLY,
        "Keysight E36300-series DC supply (E36311A/12A/13A), SCPI over LAN (VISA)",
        VISA_RESOURCE, _open_e36300,
        settings=(Setting("channel", SettingKind.INTEGER, 1, minimum=1, maximum=3,
                          doc="the output channel that powers the unit"),),
        simulator=_sim_e36300, sim_faults=SUPPLY_FAULTS,
        documents=("command spellings of PyMeasure keysightE36312A.py (E36300 programming "
                   "guide not available: unconfirmed)",)),
    DriverSpec(
        "keysight_34465a", Role.GYRO,
        "analog gyro through a Keysight Truevolt DMM (34465A/34470A, 34461A subset), DC volts "
        "on the meter's sample timer, SCPI over LAN (VISA)",
        VISA_RESOURCE, _open_truevolt,
        settings=(
            Setting("range_v", SettingKind.NUMBER, 10.0, unit="V", minimum=0.1, maximum=1000.0,
                    doc="DC volts range (0.1, 1, 10, 100 or 1000 V)"),
            Setting("aperture_s", SettingKind.NUMBER, None, unit="s", above=0.0,
                    doc="integration time per reading", default_text="0.8 / sample_rate_hz"),
            Setting("nplc", SettingKind.NUMBER, None, above=0.0,
                    doc="integration in power-line cycles (instead of aperture_s)"),
            Setting("scale_factor_v_per_dps", SettingKind.NUMBER, None, unit="V/(deg/s)",
                    required=True, doc="the unit's nominal scale factor (the report measures it)"),
            Setting("zero_v", SettingKind.NUMBER, 0.0, unit="V",
                    doc="the unit's nominal output at rest (the report measures it)"),
        ),
        simulator=_sim_truevolt, sim_faults=DMM_FAULTS, check=_one_integration,
        documents=("command spellings of QCoDeS Keysight_344xxA_submodules.py; DATA:POINts?, "
                   "DATA:REMove?, CALibration:DATE? (34465A programming guide not available: "
                   "unconfirmed)",)),
    DriverSpec(
        "keysight_53230a", Role.GYRO,
        "pulse gyro through a Keysight 53220A/53230A universal counter, timed totalize per "
        "readout, SCPI over LAN (VISA)",
        VISA_RESOURCE, _open_counter,
        settings=(
            Setting("pulse_weight_arcsec", SettingKind.NUMBER, None, unit="arcsec", above=0.0,
                    required=True, doc="angle per pulse (counts become angle through it)"),
            Setting("channel", SettingKind.INTEGER, 1, minimum=1, maximum=2,
                    doc="the counter input the pulse (up minus down) line is on"),
        ),
        simulator=_sim_counter, sim_faults=COUNTER_FAULTS,
        documents=("53220A/53230A programming guide not available: CONFigure:TOTalize:TIMed, "
                   "DATA:POINts?, DATA:REMove? unconfirmed",)),
)
