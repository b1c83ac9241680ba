"""Watlow Series F4 temperature controller over Modbus RTU.

Sources for the register map (holding registers, 0-based protocol addresses):

- 100 input 1 process value, 300 set point 1: the project brief, matching
  the open-source F4 drivers examined (e.g. Pascal Stang's ``watlowf4.py``,
  which reads 100/300 with FC 03, signed deci-degrees).
- 200 alarm status: the project brief. The bit assignment (bit 0 = alarm 1,
  bit 1 = alarm 2) is this project's assumption, not yet checked against the
  F4 communications manual; the simulator serves the same layout.
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
from gyrocal.instruments.interfaces import ChamberStatus, Identity
from gyrocal.instruments.retry import RetryPolicy

F4_MODEL_NUMBER = 5270

F4_REGISTERS: dict[str, Register] = register_table(
    Register("model", 0, Encoding.UINT16, False, "model number"),
    Register("serial_high", 1, Encoding.UINT16, False, "serial number, first part"),
    Register("serial_low", 2, Encoding.UINT16, False, "serial number, second part"),
    Register("process_value", 100, Encoding.INT16_DECIMALS, False, "input 1 process value"),
    Register("alarm_status", 200, Encoding.UINT16, False, "alarm status"),
    Register("setpoint", 300, Encoding.INT16_DECIMALS, True, "set point 1"),
)

#: Bits of the alarm status register 200 (project assumption, see module docstring).
F4_ALARM_BITS: dict[int, str] = {0x0001: "alarm 1 active", 0x0002: "alarm 2 active"}


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
        name: str = "chamber (Watlow F4)",
        check_model: bool = True,
        on_retry: Callable[[int, InstrumentError], None] | None = None,
    ) -> None:
        if not 0 <= decimals <= 3:
            raise ValueError(f"decimals must be 0..3, got {decimals!r}")
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {timeout_s!r}")
        self.address = address
        self.decimals = decimals
        self.check_model = check_model

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
                address, framer=FramerType.RTU, baudrate=baudrate, timeout=timeout_s,
                retries=0, trace_packet=trace,
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
        description = f"Watlow {model} (model register {words[0]}), serial {words[1]}-{words[2]}"
        return Identity(role="chamber", driver=self.DRIVER, address=self.address, description=description)

    def read_temperature_c(self) -> float:
        return float(self._link.read(F4_REGISTERS["process_value"], self.decimals))

    def read_setpoint_c(self) -> float:
        return float(self._link.read(F4_REGISTERS["setpoint"], self.decimals))

    def set_setpoint_c(self, setpoint_c: float) -> None:
        self._link.write(F4_REGISTERS["setpoint"], setpoint_c, self.decimals)

    def read_status(self) -> ChamberStatus:
        alarm_bits = int(self._link.read(F4_REGISTERS["alarm_status"]))
        active = [text for bit, text in F4_ALARM_BITS.items() if alarm_bits & bit]
        unknown = alarm_bits & ~sum(F4_ALARM_BITS)
        if unknown:
            active.append(f"unknown alarm bits 0x{unknown:04X}")
        return ChamberStatus(
            temperature_c=self.read_temperature_c(),
            setpoint_c=self.read_setpoint_c(),
            alarm=bool(alarm_bits),
            detail="; ".join(active),
        )

    def close(self) -> None:
        self._link.close()

    def __enter__(self) -> WatlowF4:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
