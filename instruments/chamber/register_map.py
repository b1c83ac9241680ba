"""One declaration per controller model of the registers the project uses.

Driver and simulator read the same table, so an address or an encoding lives
in exactly one place (the PyMeasure way: properties declared once, the
plumbing generic). The simulator test then checks the table against
hand-written addresses with an independent client, so a shared mistake is
still caught.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

from gyrocal.instruments.chamber import modbus_codec as codec


class Encoding(Enum):
    UINT16 = "uint16"
    INT16_DECIMALS = "int16 with implied decimals"
    FLOAT32_LWF = "float32, low word first"
    FLOAT32_HWF = "float32, high word first"
    INT32_LWF = "int32, low word first"
    TEXT = "text, one character per register"


#: The encodings that are plain pymodbus conversions: data type and word order.
_PYMODBUS: dict[Encoding, tuple[codec.DataType, codec.WordOrder]] = {
    Encoding.UINT16: (codec.DataType.UINT16, "big"),
    Encoding.FLOAT32_LWF: (codec.DataType.FLOAT32, "little"),
    Encoding.FLOAT32_HWF: (codec.DataType.FLOAT32, "big"),
    Encoding.INT32_LWF: (codec.DataType.INT32, "little"),
}


@dataclass(frozen=True)
class Register:
    """A holding register (or block) of a controller: where, how encoded, who may write."""

    name: str
    address: int
    encoding: Encoding
    writable: bool
    description: str
    text_count: int = 0           # only for Encoding.TEXT: number of registers

    @property
    def count(self) -> int:
        if self.encoding is Encoding.TEXT:
            return self.text_count
        if self.encoding is Encoding.INT16_DECIMALS:
            return 1
        return _PYMODBUS[self.encoding][0].value[1]

    @property
    def label(self) -> str:
        """How commands name it in errors, e.g. ``holding register 100 (process value)``."""
        if self.count == 1:
            return f"holding register {self.address} ({self.description})"
        return f"holding registers {self.address}-{self.address + self.count - 1} ({self.description})"

    def decode(self, registers: Sequence[int], decimals: int = 0) -> float | int | str:
        if len(registers) != self.count:
            raise ValueError(f"{self.label}: expected {self.count} register(s), got {len(registers)}")
        if self.encoding is Encoding.INT16_DECIMALS:
            return codec.decode_int16_decimals(registers[0], decimals)
        if self.encoding is Encoding.TEXT:
            return codec.decode_text_one_char_per_register(registers)
        data_type, word_order = _PYMODBUS[self.encoding]
        return codec.from_registers(registers, data_type, word_order)

    def encode(self, value: float | int | str, decimals: int = 0) -> list[int]:
        if self.encoding is Encoding.INT16_DECIMALS:
            return [codec.encode_int16_decimals(float(value), decimals)]
        if self.encoding is Encoding.TEXT:
            return codec.encode_text_one_char_per_register(str(value), self.count)
        data_type, word_order = _PYMODBUS[self.encoding]
        number = float(value) if data_type is codec.DataType.FLOAT32 else int(value)
        try:
            return codec.to_registers(number, data_type, word_order)
        except ValueError as exc:
            raise ValueError(f"{self.label}: {exc}") from exc


def register_table(*registers: Register) -> dict[str, Register]:
    """Name -> register, refusing duplicate names or overlapping addresses."""
    table: dict[str, Register] = {}
    used: dict[int, str] = {}
    for reg in registers:
        if reg.name in table:
            raise ValueError(f"register name {reg.name!r} declared twice")
        for address in range(reg.address, reg.address + reg.count):
            if address in used:
                raise ValueError(f"register {address} of {reg.name!r} overlaps {used[address]!r}")
            used[address] = reg.name
        table[reg.name] = reg
    return table
