"""Asking a STIM300 who it is at connect: ``N<CR>`` and ``I<CR>``, and what it said at start-up.

A unit in normal mode answers ``N<CR>`` with one Part Number datagram and
``I<CR>`` with one Serial Number datagram (TS1524 Table 8-1, §8.1 Table 8-3,
§8.2 Table 8-4, p. 58), each replacing the next normal-mode datagram(s),
through the same bounded wait as ``C<CR>`` (configuration_query.py). Its
serial goes into the gyro's identity description as ``serial N…``, the text
``gyrocal.instruments.identity.reported_serial`` reads, so the report's
declared-vs-reported check and the station's serial locks see it as they see
the table's and the chamber's. A unit that does not answer (a replayed
capture is one-way) is not a fault: the description says the serial is not
confirmed, in words that reader does not take for a serial.

After a power-on the unit sends its special datagrams unasked (§7.5.1,
p. 47): :class:`StartUpRecord` is what the driver cut from the stream then.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.instruments.gyro.configuration import UnitConfiguration
from gyrocal.instruments.gyro.special_datagrams import (
    BiasTrimOffset,
    Found,
    PartNumber,
    SerialNumber,
)

#: Table 8-3 (p. 58): capital N, then the execution character CR (Table 8-2)
PART_NUMBER_COMMAND = b"N\r"
#: Table 8-4 (p. 58): capital I, then CR
SERIAL_NUMBER_COMMAND = b"I\r"
#: no answer to N (no "serial" followed by a word: reported_serial must not read one)
PART_NOT_CONFIRMED = "part number: not confirmed (no answer to N, TS1524 §8.1)"
SERIAL_NOT_CONFIRMED = "serial: not confirmed (no answer to I, TS1524 §8.2)"
#: not asked: the unit left C<CR> unanswered on this line (one-way, as a replay)
NOT_ASKED = "part number, serial: not confirmed (not asked: no answer to C, TS1524 §8.3)"


@dataclass(frozen=True)
class IdentityAnswer:
    """What the unit said when asked N and I (None: that one went unanswered)."""

    part: PartNumber | None
    serial: SerialNumber | None
    asked: bool = True

    @property
    def confirmed(self) -> bool:
        return self.serial is not None

    def describe(self) -> str:
        """``unit part number 84167-… rev K, serial N…`` (the serial last, for the reader)."""
        if not self.asked:
            return f"unit {NOT_ASKED}"
        part = PART_NOT_CONFIRMED if self.part is None else self.part.describe()
        serial = SERIAL_NOT_CONFIRMED if self.serial is None else self.serial.describe()
        return f"unit {part}, {serial}"

    def record(self) -> dict[str, object]:
        """The journal's fields (JSON)."""
        return {"part_number": None if self.part is None else self.part.part_number,
                "revision": None if self.part is None else self.part.revision,
                "serial": None if self.serial is None else self.serial.serial,
                "description": self.describe()}


@dataclass(frozen=True)
class StartUpRecord:
    """The special datagrams a unit sent after a power-on (§7.5.1), as cut from the stream."""

    found: tuple[Found, ...]

    def _value(self, cls: type):
        return next((f.value for f in self.found if isinstance(f.value, cls)), None)

    def record(self) -> dict[str, object]:
        """The journal's fields (JSON): what each datagram said, in the order received."""
        part, serial = self._value(PartNumber), self._value(SerialNumber)
        config, trim = self._value(UnitConfiguration), self._value(BiasTrimOffset)
        return {
            "datagrams": [f.kind.name for f in self.found],
            "part_number": None if part is None else part.part_number,
            "revision": None if part is None else part.revision,
            "serial": None if serial is None else serial.serial,
            "configuration": None if config is None else config.describe(),
            "bias_trim_offset": None if trim is None else trim.describe(),
        }
