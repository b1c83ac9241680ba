"""Watlow F4T touch-screen controller over Modbus TCP.

Register map (holding registers, 0-based protocol addresses, control loop 1,
alarm 1). Sources: the F4T "Setup and Operations User's Guide"
(0600-0093-0000, chapter 6 appendix, as reproduced on easymanua.ls pages 225
and 231) for 0/4/12/16-30/90/1330+ and the loop block at 2774+; Espec North
America's open-source F4T controller class (``get_loop_sp`` 2782,
``get_loop_pv`` 2820, ``get_alarm_status`` 1356, ``process_controller`` part
number at 16, 15 registers) for the loop addresses and the alarm state.

- float32 and int32 values span two registers, **low word first**;
- strings hold one character per register (low byte);
- alarm state 1356: 61 "none", 88 "startup" and 12 "blocked" mean no alarm,
  every other value (e.g. alarm high / alarm low / error) is an active alarm,
  which is how the Espec driver reads it (28 "error" is in its value table;
  the codes 7 "alarm high" and 8 "alarm low" used by the simulator are this
  project's assumption, and any non-quiet code is reported as an alarm anyway);
- device status 90: 138 "OK", 32 "Fail";
- profile state 16568 (Espec ``get_status``, read on every F4T whatever its
  options): 149 "running", 146 "paused" — the controller runs (or holds) its
  own profile and preflight refuses to drive it; 1783 is Espec's "calendar
  start" (reported, not refused); any other value is no profile running;
- display units 1328 (same guide, p. 225, "Display Units": F (30), C (15), default F (30),
  unsigned 16-bit RW). Temperatures and set points on Modbus are in the display units, so
  a factory-default controller speaks °F: the driver reads 1328 at connect and converts
  every temperature to and from °C; a value other than 30 or 15 is a fault naming the
  register.

``address`` is ``host:port`` or ``host`` (port 502). One driver instance per
thread (see :mod:`modbus_link`).
"""

from __future__ import annotations

from collections.abc import Callable

from pymodbus.client import ModbusTcpClient
from pymodbus.framer import FramerType

from gyrocal.instruments.chamber.modbus_link import ModbusLink
from gyrocal.instruments.chamber.register_map import Encoding, Register, register_table
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.interfaces import ChamberStatus, ChamberUnits, Identity
from gyrocal.instruments.retry import RetryPolicy

F4T_REGISTERS: dict[str, Register] = register_table(
    Register("software_release", 4, Encoding.INT32_LWF, False, "software release version"),
    Register("serial_number", 12, Encoding.INT32_LWF, False, "serial number"),
    Register("part_number", 16, Encoding.TEXT, False, "F4T part number", text_count=15),
    Register("device_status", 90, Encoding.UINT16, False, "device status"),
    Register("display_units", 1328, Encoding.UINT16, True, "display units"),
    Register("alarm1_state", 1356, Encoding.UINT16, False, "alarm 1 state"),
    Register("setpoint", 2782, Encoding.FLOAT32_LWF, True, "control loop 1 set point"),
    Register("process_value", 2820, Encoding.FLOAT32_LWF, False, "control loop 1 process value"),
    Register("profile_state", 16568, Encoding.UINT16, False, "profile state"),
)

#: float word order: the guide's and Espec's low word first; "high_first" for a controller
#: or gateway set to swap them (a station-file setting, chamber.word_order)
WORD_ORDERS = ("low_first", "high_first")


def f4t_registers(word_order: str = "low_first") -> dict[str, Register]:
    """The register map with its float encoding in ``word_order``."""
    if word_order not in WORD_ORDERS:
        raise ValueError(f"word_order must be one of {WORD_ORDERS}, got {word_order!r}")
    if word_order == "low_first":
        return F4T_REGISTERS
    return {name: (Register(r.name, r.address, Encoding.FLOAT32_HWF, r.writable, r.description)
                   if r.encoding is Encoding.FLOAT32_LWF else r)
            for name, r in F4T_REGISTERS.items()}


DISPLAY_UNITS_F = 30          # factory default (F4T guide, chapter 6, Display Units)
DISPLAY_UNITS_C = 15
DEVICE_STATUS_OK = 138
DEVICE_STATUS_FAIL = 32
ALARM_STATE_NONE = 61
ALARM_STATE_STARTUP = 88
ALARM_STATE_BLOCKED = 12
ALARM_STATE_HIGH = 7
ALARM_STATE_LOW = 8
ALARM_STATE_ERROR = 28
PROFILE_STATE_RUNNING = 149     # Espec watlowf4t.py get_status / value table
PROFILE_STATE_PAUSED = 146
PROFILE_STATE_CALENDAR_START = 1783
PROFILE_STATE_TEXT = {PROFILE_STATE_RUNNING: "profile running", PROFILE_STATE_PAUSED: "profile paused",
                      PROFILE_STATE_CALENDAR_START: "constant (profile calendar start)"}
ALARM_QUIET_STATES = frozenset({ALARM_STATE_NONE, ALARM_STATE_STARTUP, ALARM_STATE_BLOCKED})
ALARM_STATE_TEXT = {
    ALARM_STATE_NONE: "none", ALARM_STATE_STARTUP: "startup", ALARM_STATE_BLOCKED: "blocked",
    ALARM_STATE_HIGH: "alarm high", ALARM_STATE_LOW: "alarm low", ALARM_STATE_ERROR: "error",
}


def parse_tcp_address(address: str, default_port: int = 502) -> tuple[str, int]:
    """``"host:port"`` or ``"host"`` -> (host, port); a clear error for anything else."""
    host, sep, port_text = address.rpartition(":")
    if not sep:
        return address, default_port
    if not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"F4T address must be 'host:port' or 'host', got {address!r}")
    return host, int(port_text)


class WatlowF4T:
    """Chamber driver for a Watlow F4T (satisfies ``interfaces.Chamber``)."""

    DRIVER = "watlow_f4t"

    def __init__(
        self,
        address: str,
        *,
        unit_id: int = 1,
        timeout_s: float = 1.0,
        retry: RetryPolicy | None = None,
        name: str = "chamber (Watlow F4T)",
        word_order: str = "low_first",
        on_retry: Callable[[int, InstrumentError], None] | None = None,
    ) -> None:
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {timeout_s!r}")
        self.address = address
        self.registers = f4t_registers(word_order)
        host, port = parse_tcp_address(address)

        def make_client(trace: Callable[[bool, bytes], bytes]) -> ModbusTcpClient:
            return ModbusTcpClient(
                host, port=port, framer=FramerType.SOCKET, timeout=timeout_s, retries=0,
                trace_packet=trace,
            )

        self._link = ModbusLink(name, make_client, unit_id, timeout_s, retry or RetryPolicy(), on_retry)
        self._fahrenheit: bool | None = None     # read from register 1328 at the first use

    @property
    def name(self) -> str:
        return self._link.instrument

    def identify(self) -> Identity:
        part = self._link.read(self.registers["part_number"])
        serial = self._link.read(self.registers["serial_number"])
        release = self._link.read(self.registers["software_release"])
        units = "°F (converted to °C)" if self.fahrenheit else "°C"
        description = (f"Watlow F4T part {part or '?'}, serial {serial}, software release {release}, "
                       f"display units {units} (register 1328)")
        return Identity(role="chamber", driver=self.DRIVER, address=self.address, description=description)

    @property
    def fahrenheit(self) -> bool:
        """Does the controller speak °F on Modbus (display units, register 1328)?"""
        if self._fahrenheit is None:
            code = int(self._link.read(self.registers["display_units"]))
            if code not in (DISPLAY_UNITS_F, DISPLAY_UNITS_C):
                raise InstrumentError(
                    self.name, "read display units", f"holding register 1328 (display units) "
                    f"reads {code}, neither F (30) nor C (15); set Display Units on the "
                    "controller's front panel (Settings > Global)", reply=str(code))
            self._fahrenheit = code == DISPLAY_UNITS_F
        return self._fahrenheit

    def read_units(self) -> ChamberUnits:
        """Display Units (1328), read from the controller now; values are float32."""
        self._fahrenheit = None
        return ChamberUnits(self.fahrenheit, None, "register 1328")

    def _read_c(self, name: str) -> float:
        fahrenheit = self.fahrenheit          # the units first: 1328 is read once, before any value
        value = float(self._link.read(self.registers[name]))
        return (value - 32.0) / 1.8 if fahrenheit else value

    def read_temperature_c(self) -> float:
        return self._read_c("process_value")

    def read_setpoint_c(self) -> float:
        return self._read_c("setpoint")

    def set_setpoint_c(self, setpoint_c: float) -> None:
        value = setpoint_c * 1.8 + 32.0 if self.fahrenheit else setpoint_c
        self._link.write(self.registers["setpoint"], value)

    def read_status(self) -> ChamberStatus:
        alarm_state = int(self._link.read(self.registers["alarm1_state"]))
        device_status = int(self._link.read(self.registers["device_status"]))
        problems = []
        if alarm_state not in ALARM_QUIET_STATES:
            problems.append(f"alarm 1 {ALARM_STATE_TEXT.get(alarm_state, f'state {alarm_state}')}")
        if device_status != DEVICE_STATUS_OK:
            problems.append(
                "device status fail" if device_status == DEVICE_STATUS_FAIL else f"device status {device_status}"
            )
        profile_state = int(self._link.read(self.registers["profile_state"]))
        return ChamberStatus(
            temperature_c=self.read_temperature_c(),
            setpoint_c=self.read_setpoint_c(),
            alarm=bool(problems),
            detail="; ".join(problems),
            profile_running=profile_state in (PROFILE_STATE_RUNNING, PROFILE_STATE_PAUSED),
            run_state=PROFILE_STATE_TEXT.get(profile_state, "constant"),
        )

    def reset_link(self) -> None:
        self._link.reset()

    def close(self) -> None:
        self._link.close()

    def __enter__(self) -> WatlowF4T:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
