"""Pure encodings between engineering values and Modbus registers.

Kept free of any I/O so that each can be pinned by byte pairs taken from the
controller manuals: a wrong word order or a sign slip here would silently
shift every temperature of a calibration run.

The register conversions themselves (16/32-bit integers and float32 in either
word order) are pymodbus's (``ModbusClientMixin.convert_to_registers`` /
``convert_from_registers``); this module adds only what the controllers add
on top, and turns a value that does not fit into a ``ValueError`` the link
names the register by:

- Watlow F4 (Series F4, Modbus RTU): signed 16-bit integers with an implied
  number of decimals (``23.1 °C`` with 1 decimal is ``231`` = ``0x00E7``).
- Watlow F4T (Modbus TCP): IEEE-754 float32 in two registers, **low word
  first** (``25.0`` = ``0x41C80000`` is sent as ``[0x0000, 0x41C8]``); signed
  32-bit integers use the same word order; text holds one character in each
  register's low byte (pymodbus's strings pack two per register, so that one
  stays here).

RTU framing and its CRC-16 are pymodbus's too (the link); the tests pin them against the
manual's frames with a textbook CRC of their own (``tests/support/modbus_rtu.py``).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Literal

from pymodbus.client.mixin import ModbusClientMixin

DataType = ModbusClientMixin.DATATYPE
WordOrder = Literal["big", "little"]

INT16_MIN = -0x8000
INT16_MAX = 0x7FFF


def to_registers(value: float | int, data_type: DataType, word_order: WordOrder) -> list[int]:
    """A number -> its registers, by pymodbus; a value the type cannot hold is a ValueError."""
    try:
        return ModbusClientMixin.convert_to_registers(value, data_type, word_order=word_order)
    except (struct.error, OverflowError) as exc:
        raise ValueError(f"{value!r} does not fit a Modbus {data_type.name.lower()}: {exc}") from exc


def from_registers(registers: Sequence[int], data_type: DataType,
                   word_order: WordOrder) -> float | int:
    """Registers -> a number, by pymodbus, after checking the count and each register's range."""
    count = data_type.value[1]
    if len(registers) != count:
        raise ValueError(f"expected {count} register(s), got {len(registers)}: {list(registers)!r}")
    for register in registers:
        _check_register(register)
    value = ModbusClientMixin.convert_from_registers(list(registers), data_type,
                                                     word_order=word_order)
    if not isinstance(value, int | float):  # the numeric types above give one number
        raise TypeError(f"pymodbus returned {value!r} for {data_type.name}")
    return value


def encode_int16_decimals(value: float, decimals: int) -> int:
    """Engineering value -> one register (0..65535, two's complement)."""
    if not math.isfinite(value):
        raise ValueError(f"cannot encode {value!r} as a Modbus int16")
    scaled = round(value * 10**decimals)
    if not INT16_MIN <= scaled <= INT16_MAX:
        raise ValueError(
            f"{value} with {decimals} implied decimal(s) is {scaled}, outside int16 "
            f"[{INT16_MIN}, {INT16_MAX}]"
        )
    return to_registers(scaled, DataType.INT16, "big")[0]


def decode_int16_decimals(register: int, decimals: int) -> float:
    """One register (0..65535) -> engineering value, reading bit 15 as the sign."""
    return from_registers([register], DataType.INT16, "big") / 10**decimals


def encode_text_one_char_per_register(text: str, count: int) -> list[int]:
    """F4T strings hold one character in each register's low byte, zero padded."""
    codes = [ord(ch) for ch in text[:count]]
    if any(code > 0xFF for code in codes):
        raise ValueError(f"{text!r} is not representable one byte per register")
    return codes + [0] * (count - len(codes))


def decode_text_one_char_per_register(registers: Sequence[int]) -> str:
    return "".join(chr(reg & 0xFF) for reg in registers if reg & 0xFF).strip()


def _check_register(register: int) -> None:
    if not 0 <= register <= 0xFFFF:
        raise ValueError(f"register value {register!r} outside 0..65535")
