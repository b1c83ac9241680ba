"""Pure encodings between engineering values and Modbus registers.

Kept free of any I/O so that each can be pinned by byte pairs taken from the
controller manuals: a wrong word order or a sign slip here would silently
shift every temperature of a calibration run.

- Watlow F4 (Series F4, Modbus RTU): signed 16-bit integers with an implied
  number of decimals (``23.1 °C`` with 1 decimal is ``231`` = ``0x00E7``).
- Watlow F4T (Modbus TCP): IEEE-754 float32 in two registers, **low word
  first** (``25.0`` = ``0x41C80000`` is sent as ``[0x0000, 0x41C8]``); signed
  32-bit integers use the same word order.

RTU framing and its CRC-16 are pymodbus's (the link); the tests pin them against the
manual's frames with a textbook CRC of their own (``tests/support/modbus_rtu.py``).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

INT16_MIN = -0x8000
INT16_MAX = 0x7FFF


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
    return scaled & 0xFFFF


def decode_int16_decimals(register: int, decimals: int) -> float:
    """One register (0..65535) -> engineering value, reading bit 15 as the sign."""
    _check_register(register)
    signed = register - 0x10000 if register & 0x8000 else register
    return signed / 10**decimals


def encode_float32_low_word_first(value: float) -> list[int]:
    """float32 -> [low word, high word]."""
    high, low = struct.unpack(">HH", struct.pack(">f", value))
    return [low, high]


def decode_float32_low_word_first(registers: Sequence[int]) -> float:
    """[low word, high word] -> float (as float32 precision allows)."""
    low, high = _two_registers(registers)
    return struct.unpack(">f", struct.pack(">HH", high, low))[0]


def encode_float32_high_word_first(value: float) -> list[int]:
    """float32 -> [high word, low word] (plain big-endian; a word-order setting some gateways use)."""
    high, low = struct.unpack(">HH", struct.pack(">f", value))
    return [high, low]


def decode_float32_high_word_first(registers: Sequence[int]) -> float:
    high, low = _two_registers(registers)
    return struct.unpack(">f", struct.pack(">HH", high, low))[0]


def encode_int32_low_word_first(value: int) -> list[int]:
    high, low = struct.unpack(">HH", struct.pack(">i", int(value)))
    return [low, high]


def decode_int32_low_word_first(registers: Sequence[int]) -> int:
    low, high = _two_registers(registers)
    return struct.unpack(">i", struct.pack(">HH", high, low))[0]


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


def _two_registers(registers: Sequence[int]) -> tuple[int, int]:
    if len(registers) != 2:
        raise ValueError(f"expected 2 registers, got {len(registers)}: {list(registers)!r}")
    for reg in registers:
        _check_register(reg)
    return registers[0], registers[1]
