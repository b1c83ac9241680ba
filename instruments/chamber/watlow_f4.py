"""Watlow Series F4 temperature controller over Modbus RTU.

Sources for the register map (holding registers, 0-based protocol addresses):

- 100 input 1 process value, 300 set point 1: the project brief, matching
  the open-source F4 drivers examined (e.g. Pascal Stang's ``watlowf4.py``,
  which reads 100/300 with FC 03, signed deci-degrees).
- 200 is NOT an alarm register (an earlier version read it as one): it is the
  controller's run state — 0/1 constant set point, 2 profile running, 3 profile
  paused — in Espec North America's open-source F4 driver (ChamberConnectLibrary
  ``watlowf4.py``, ``get_status``/``get_loop_sp``). Preflight refuses to start
  while the controller runs its own profile.
- Limit alarm: the limit controller is wired to a digital input, and the input
  is ACTIVE when its state equals its condition. Watlow Series F4P user's
  manual, ch. 9 Modbus register list: 201 + 12·(N−1) "Digital Input N, Status"
  (read; 0 low, 1 high; p. 9.5) and 1061 + 2·(N−1) "Condition, Digital Input
  N" (0 low, 1 high; p. 9.4; Setup Page table p. 6.18: the condition that
  triggers the input); features p. 7.4: the input's event lasts as long as
  that state exists. Espec's driver agrees since its fix 13600df (its
  ``__get_digital_input`` returns state ≠ condition and files such an input
  under *inactive* alarms). An earlier release of this driver read
  state ≠ condition as "tripped": inverted, a tripped limit read healthy.
  The station's ``chamber.limit_input: N`` names that input; without it the
  driver reports no alarm and says so in its identity.
- 901 temperature units (nonzero °C, 0 °F) and 606 input 1 decimal places: read
  by the same Espec driver (``get_loop_units``, ``__get_scalar``). Read at
  connect (``identify``): °F is converted to and from °C, and the decimals the
  controller reports replace the configured ones (0..3; anything else is a
  fault naming the register).
- 0 model number (5270 for a Series F4; the decimal digits "52","70" are the
  ASCII codes of "4" and "F"), 1-2 serial number: from an open-source F4
  chamber driver that reads them for identification; not seen in a Watlow
  manual here. :meth:`WatlowF4.identify` reports what it read; with
  ``check_model`` (default) it refuses any other model value, so a wrong box
  on the line is caught; pass ``check_model=False`` if a real F4 disagrees.

Values are signed 16-bit with implied decimals: 1 decimal for °C by default
(the F4 "decimal places" setting of input 1 must match ``decimals``).

Transport: ``address`` is a pyserial URL, so both ``/dev/ttyUSB0`` (or
``COM3``) and ``socket://host:port`` (RTU frames over a TCP serial gateway,
as the simulator serves them) go through the same serial client and framer.

One driver instance per thread (see :mod:`modbus_link`).
"""

from __future__ import annotations

from collections.abc import Callable

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.framer import FramerType

from gyrocal.instruments.chamber.modbus_link import ModbusLink
from gyrocal.instruments.chamber.register_map import Encoding, Register, register_table
from gyrocal.instruments.errors import InstrumentError, InstrumentProtocolError
from gyrocal.instruments.interfaces import ChamberStatus, ChamberUnits, Identity
from gyrocal.instruments.retry import RetryPolicy

F4_MODEL_NUMBER = 5270

F4_REGISTERS: dict[str, Register] = register_table(
    Register("model", 0, Encoding.UINT16, False, "model number"),
    Register("serial_high", 1, Encoding.UINT16, False, "serial number, first part"),
    Register("serial_low", 2, Encoding.UINT16, False, "serial number, second part"),
    Register("process_value", 100, Encoding.INT16_DECIMALS, False, "input 1 process value"),
    Register("profile_state", 200, Encoding.UINT16, False, "run state (profile)"),
    Register("setpoint", 300, Encoding.INT16_DECIMALS, True, "set point 1"),
    Register("input1_decimals", 606, Encoding.UINT16, False, "input 1 decimal places"),
    Register("temperature_units", 901, Encoding.UINT16, False, "temperature units"),
)

#: Register 200 (Espec watlowf4.py): 0, 1 constant set point; 2 profile running; 3 paused.
PROFILE_RUNNING, PROFILE_PAUSED = 2, 3
PROFILE_STATE_TEXT = {0: "constant", 1: "constant", PROFILE_RUNNING: "profile running",
                      PROFILE_PAUSED: "profile paused"}


#: Digital input condition / status values (F4P manual pp. 9.4-9.5): 0 low, 1 high.
DIGITAL_LEVELS = {0: "low", 1: "high"}


def digital_input_registers(number: int) -> tuple[Register, Register]:
    """(status, condition) of digital input ``number`` (1-4), F4P manual pp. 9.4-9.5."""
    if not 1 <= number <= 4:
        raise ValueError(f"digital input must be 1..4, got {number!r}")
    return (Register(f"di{number}_state", 201 + 12 * (number - 1), Encoding.UINT16, False,
                     f"digital input {number} status"),
            Register(f"di{number}_condition", 1061 + 2 * (number - 1), Encoding.UINT16, False,
                     f"digital input {number} condition"))


def f4_model_text(model_register: int) -> str:
    """5270 -> "F4": the register holds the ASCII codes of the characters, reversed."""
    digits = f"{model_register:04d}"
    try:
        return chr(int(digits[2:])) + chr(int(digits[:2]))
    except ValueError:
        return "?"


class WatlowF4:
    """Chamber driver for a Watlow Series F4 (satisfies ``interfaces.Chamber``)."""

    DRIVER = "watlow_f4"

    def __init__(
        self,
        address: str,
        *,
        unit_id: int = 1,
        decimals: int = 1,
        timeout_s: float = 1.0,
        retry: RetryPolicy | None = None,
        baudrate: int = 9600,
        parity: str = "N",
        stop_bits: int = 1,
        name: str = "chamber (Watlow F4)",
        check_model: bool = True,
        limit_input: int | None = None,
        on_retry: Callable[[int, InstrumentError], None] | None = None,
    ) -> None:
        if parity not in ("N", "E", "O") or stop_bits not in (1, 2):
            raise ValueError(f"serial settings: parity N/E/O and stop bits 1/2, got "
                             f"{parity!r}/{stop_bits!r}")
        if not 0 <= decimals <= 3:
            raise ValueError(f"decimals must be 0..3, got {decimals!r}")
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {timeout_s!r}")
        self.address = address
        self.decimals = decimals
        self.fahrenheit = False        # read from register 901 at connect (identify)
        self.check_model = check_model
        self.limit_input = limit_input
        self._limit_registers = None if limit_input is None else digital_input_registers(limit_input)

        def make_client(trace: Callable[[bool, bytes], bytes]) -> ModbusSerialClient | ModbusTcpClient:
            if address.startswith("socket://"):
                # A serial-to-Ethernet bridge: the same RTU frames, carried by TCP.
                # pymodbus' TCP transport waits on the socket; its serial transport
                # polls a pyserial socket:// URL with sleeps (~10 ms a read), which
                # would dominate a dry run's wall time. Bytes on the wire are identical.
                host, _, port = address[len("socket://"):].rpartition(":")
                return ModbusTcpClient(
                    host, port=int(port), framer=FramerType.RTU, timeout=timeout_s,
                    retries=0, trace_packet=trace,
                )
            return ModbusSerialClient(
                address, framer=FramerType.RTU, baudrate=baudrate, parity=parity,
                stopbits=stop_bits, timeout=timeout_s, retries=0, trace_packet=trace,
            )

        self._link = ModbusLink(name, make_client, unit_id, timeout_s, retry or RetryPolicy(), on_retry)

    @property
    def name(self) -> str:
        return self._link.instrument

    def identify(self) -> Identity:
        words = self._link.read_raw(0, 3, "model and serial number")
        model = f4_model_text(words[0])
        if self.check_model and words[0] != F4_MODEL_NUMBER:
            raise InstrumentProtocolError(
                self.name, "read holding registers 0-2 (model and serial number)",
                f"model register reads {words[0]} ({model!r}); a Series F4 reports {F4_MODEL_NUMBER} ('F4')",
                reply=str(words),
            )
        alarms = (f"limit controller on digital input {self.limit_input}" if self.limit_input
                  else "alarms NOT monitored (no chamber.limit_input in the station)")
        self._read_units()
        units = "°F (converted to °C)" if self.fahrenheit else "°C"
        description = (f"Watlow {model} (model register {words[0]}), serial {words[1]}-{words[2]}, "
                       f"units {units} (register 901), {self.decimals} decimal(s) (register 606), "
                       f"{alarms}")
        return Identity(role="chamber", driver=self.DRIVER, address=self.address, description=description)

    def _read_units(self) -> None:
        """Units (901) and input 1 decimals (606), as the controller is set up."""
        decimals = int(self._link.read(F4_REGISTERS["input1_decimals"]))
        if not 0 <= decimals <= 3:
            raise InstrumentProtocolError(
                self.name, "read holding register 606 (input 1 decimal places)",
                f"reads {decimals}; expected 0..3", reply=str(decimals))
        self.decimals = decimals
        self.fahrenheit = int(self._link.read(F4_REGISTERS["temperature_units"])) == 0

    def read_units(self) -> ChamberUnits:
        """Units (901) and input 1 decimals (606), read from the controller now."""
        self._read_units()
        return ChamberUnits(self.fahrenheit, self.decimals, "registers 901, 606")

    def _to_c(self, value: float) -> float:
        return (value - 32.0) / 1.8 if self.fahrenheit else value

    def read_temperature_c(self) -> float:
        return self._to_c(float(self._link.read(F4_REGISTERS["process_value"], self.decimals)))

    def read_setpoint_c(self) -> float:
        return self._to_c(float(self._link.read(F4_REGISTERS["setpoint"], self.decimals)))

    def set_setpoint_c(self, setpoint_c: float) -> None:
        value = setpoint_c * 1.8 + 32.0 if self.fahrenheit else setpoint_c
        self._link.write(F4_REGISTERS["setpoint"], value, self.decimals)

    def limit_tripped(self) -> bool:
        """True when the limit controller's digital input is active: its status EQUALS its
        condition (F4P manual pp. 9.4-9.5, 6.18, 7.4). A value other than 0/1 is a fault."""
        if self._limit_registers is None:
            return False
        status_reg, condition_reg = self._limit_registers
        values = []
        for register in (status_reg, condition_reg):
            value = int(self._link.read(register))
            if value not in DIGITAL_LEVELS:
                raise InstrumentProtocolError(
                    self.name, f"read {register.label}",
                    f"reads {value}; the manual's values are 0 (low) and 1 (high)", reply=str(value))
            values.append(value)
        return values[0] == values[1]

    def read_status(self) -> ChamberStatus:
        state = int(self._link.read(F4_REGISTERS["profile_state"]))
        problems = []
        tripped = self.limit_tripped()
        if tripped:
            problems.append(f"alarm: limit controller tripped (digital input {self.limit_input})")
        return ChamberStatus(
            temperature_c=self.read_temperature_c(),
            setpoint_c=self.read_setpoint_c(),
            alarm=tripped,
            detail="; ".join(problems),
            profile_running=state in (PROFILE_RUNNING, PROFILE_PAUSED),
            run_state=PROFILE_STATE_TEXT.get(state, f"state {state}"),
        )

    def reset_link(self) -> None:
        self._link.reset()

    def close(self) -> None:
        self._link.close()

    def __enter__(self) -> WatlowF4:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
