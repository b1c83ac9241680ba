"""The STIM300's special datagrams: part number, serial number, configuration, bias trim offset.

A unit sends them at start-up, in that order (the bias trim offset only when
configured to, Table 5-16 byte 21 bit 1), before its first normal-mode
datagram (TS1524 §7.5.1, p. 47; Table 5-2 Note 1, p. 8), and one of them
on a Normal Mode command (Table 8-1, p. 58: ``N``, ``I``, ``C``, ``T``),
in place of the next normal-mode datagram(s) (§8.1–8.4, pp. 58–59). Each is
an identifier (a second one with CR LF), a fixed body, a CRC-32 over the body
and the dummy bytes of Table 5-22 (p. 38), then CR LF if chosen.

Layouts, typed from the tables:

* Part Number (Table 5-13, p. 29; Table 5-14, p. 29): 0xB1 / 0xB3; byte 1
  bits 3–0 digit 1; bytes 2, 3, 5, 6, 7 two nibbles each (high first:
  P2 … P11); bytes 4 and 8 '-'; bytes 9–11 nibbles P12 … P17, of which
  digit 12 is P17, digit 13 is P12 + 16·P16, digit 14 P13, digit 15
  P14 + 16·P15 (the table's "24" is 2⁴ flattened by the text extraction);
  a digit value below 10 is the ASCII digit, from 10 a capital letter
  (value + 55); byte 15 the revision character; 16 bytes before the CRC.
* Serial Number (Table 5-15, p. 30): 0xB5 / 0xB7; byte 1 'N'; bytes 2–8
  fourteen BCD digits, high nibble first; 16 bytes before the CRC. The unit's
  serial is the 'N' and the digits, as it lists them entering Service Mode (§8.7,
  Figure 8-1, p. 60).
* Bias Trim Offset (Table 5-17, p. 34): 0xD1 / 0xD2; bytes 1–27 nine 24-bit
  two's complement offsets (gyro x y z in the rate LSB of §7.5.2.2.2,
  accelerometers, inclinometers), bytes 28–31 reference of the last
  adjustment, 32–33 remaining saves; 36 bytes before the CRC.
* Configuration (Table 5-16, pp. 31–33): configuration.py.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from gyrocal.instruments.gyro.configuration import UnitConfiguration, decode_configuration
from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2, crc32_mpeg2_rows
from gyrocal.instruments.gyro.datagram import DEFAULT_LSB


@dataclass(frozen=True)
class PartNumber:
    """Table 5-13: the unit's part number (``84167-4400003-321`` form) and revision."""

    part_number: str
    revision: str

    def describe(self) -> str:
        return f"part number {self.part_number} rev {self.revision}"


@dataclass(frozen=True)
class SerialNumber:
    """Table 5-15: the unit's serial, 'N' and fourteen digits."""

    serial: str

    def describe(self) -> str:
        return f"serial {self.serial}"


@dataclass(frozen=True)
class BiasTrimOffset:
    """Table 5-17: the user's bias trim offsets (raw counts for the accelerometers and
    inclinometers, whose scale depends on their range)."""

    gyro_dps: tuple[float, float, float]
    accelerometer_counts: tuple[int, int, int]
    inclinometer_counts: tuple[int, int, int]
    reference: int
    saves_left: int

    def describe(self) -> str:
        gyro = "/".join(f"{v:g}" for v in self.gyro_dps)
        return f"bias trim offset gyro {gyro} °/s, {self.saves_left} saves left"


SpecialValue = PartNumber | SerialNumber | UnitConfiguration | BiasTrimOffset


@dataclass(frozen=True)
class SpecialKind:
    """One special datagram's framing: identifiers (plain, with CR LF), body length, dummy bytes."""

    name: str
    identifiers: tuple[int, int]
    body_bytes: int                   # the identifier and everything before the CRC
    dummy_bytes: int                  # Table 5-22
    decode_body: Callable[[bytes], SpecialValue]

    def length(self, identifier: int) -> int:
        return self.body_bytes + 4 + (2 if identifier == self.identifiers[1] else 0)


def _digit(value: int) -> str:
    """Table 5-14: below 10 the ASCII digit (+48), from 10 a capital letter (+55)."""
    return chr(value + (48 if value < 10 else 55))


def _decode_part_number(body: bytes) -> PartNumber:
    nib = [body[1] & 0x0F]                       # P1
    for index in (2, 3, 5, 6, 7, 9, 10, 11):     # P2 … P17, high nibble first
        nib += [body[index] >> 4, body[index] & 0x0F]
    p = dict(enumerate(nib, start=1))
    digits = [p[i] for i in range(1, 12)] + [p[17], p[12] + 16 * p[16], p[13], p[14] + 16 * p[15]]
    text = "".join(_digit(d) for d in digits)
    return PartNumber(f"{text[:5]}-{text[5:12]}-{text[12:]}", chr(body[15]))


def _decode_serial(body: bytes) -> SerialNumber:
    if body[1] != ord("N"):
        raise ValueError("serial number datagram: byte 1 is not 'N' (Table 5-15)")
    digits = "".join(f"{b >> 4:d}{b & 0x0F:d}" for b in body[2:9])
    if not digits.isdigit() or len(digits) != 14:
        raise ValueError("serial number datagram: a digit is not BCD (Table 5-15)")
    return SerialNumber("N" + digits)


def _int24(body: bytes, offset: int) -> int:
    return int.from_bytes(body[offset:offset + 3], "big", signed=True)


def _decode_bias_trim(body: bytes) -> BiasTrimOffset:
    gx, gy, gz, ax, ay, az, ix, iy, iz = (_int24(body, 1 + 3 * i) for i in range(9))
    return BiasTrimOffset(
        gyro_dps=(gx * DEFAULT_LSB, gy * DEFAULT_LSB, gz * DEFAULT_LSB),
        accelerometer_counts=(ax, ay, az), inclinometer_counts=(ix, iy, iz),
        reference=int.from_bytes(body[28:32], "big"),
        saves_left=int.from_bytes(body[32:34], "big"))


def _decode_configuration_body(body: bytes) -> UnitConfiguration:
    crc = crc32_mpeg2(body + bytes(CONFIGURATION.dummy_bytes))
    crlf = b"\r\n" if body[0] == CONFIGURATION.identifiers[1] else b""
    return decode_configuration(body + crc.to_bytes(4, "big") + crlf)


PART_NUMBER = SpecialKind("part number", (0xB1, 0xB3), 16, 0, _decode_part_number)
SERIAL_NUMBER = SpecialKind("serial number", (0xB5, 0xB7), 16, 0, _decode_serial)
CONFIGURATION = SpecialKind("configuration", (0xBC, 0xBD), 22, 2, _decode_configuration_body)
BIAS_TRIM_OFFSET = SpecialKind("bias trim offset", (0xD1, 0xD2), 36, 0, _decode_bias_trim)
#: what a unit sends at start-up, in order (§7.5.1)
START_UP = (PART_NUMBER, SERIAL_NUMBER, CONFIGURATION, BIAS_TRIM_OFFSET)
_LONGEST = max(k.length(k.identifiers[1]) for k in START_UP)


@dataclass(frozen=True)
class Found:
    """A special datagram whose CRC checks, where it lies in the bytes searched."""

    start: int
    end: int
    kind: SpecialKind
    value: SpecialValue


def decode_special(frame: bytes, kinds: tuple[SpecialKind, ...] = START_UP) -> Found:
    """Decode one whole special datagram; ``ValueError`` on a wrong identifier, length or CRC."""
    kind = next((k for k in kinds if frame[:1] and frame[0] in k.identifiers), None)
    if kind is None:
        raise ValueError("not a special datagram of the kinds asked for")
    if len(frame) != kind.length(frame[0]):
        raise ValueError(f"a {kind.name} datagram is {kind.length(frame[0])} bytes, got {len(frame)}")
    body = bytes(frame[:kind.body_bytes])
    stored = int.from_bytes(frame[kind.body_bytes:kind.body_bytes + 4], "big")
    if crc32_mpeg2(body + bytes(kind.dummy_bytes)) != stored:
        raise ValueError(f"{kind.name} datagram: CRC does not check")
    if frame[0] == kind.identifiers[1] and frame[-2:] != b"\r\n":
        raise ValueError(f"{kind.name} datagram: no CR LF after the CRC")
    return Found(0, len(frame), kind, kind.decode_body(body))


def _crc_valid_starts(buf: np.ndarray, kind: SpecialKind, start: int) -> np.ndarray:
    """Where a datagram of ``kind`` with a checking CRC begins, at or after ``start``
    (vectorised: a stream's payload holds many bytes that look like identifiers)."""
    body, framed = kind.body_bytes, kind.body_bytes + 4
    starts = np.flatnonzero(np.isin(buf[start:], kind.identifiers)) + start
    starts = starts[starts + framed <= buf.size]
    if not starts.size:
        return starts
    windows = sliding_window_view(buf, framed)[starts]
    message = np.zeros((starts.size, body + kind.dummy_bytes), dtype=np.uint8)
    message[:, :body] = windows[:, :body]
    stored = windows[:, body:].astype(np.uint32)
    stored = stored[:, 0] << 24 | stored[:, 1] << 16 | stored[:, 2] << 8 | stored[:, 3]
    return starts[crc32_mpeg2_rows(message) == stored]


def locate_special(data: bytes | bytearray, kinds: tuple[SpecialKind, ...] = START_UP,
                   start: int = 0) -> Found | None:
    """The first whole datagram of ``kinds`` at or after ``start`` whose CRC checks."""
    buf = np.frombuffer(bytes(data), dtype=np.uint8)
    starts = sorted((int(at), kind) for kind in kinds for at in _crc_valid_starts(buf, kind, start))
    for at, kind in starts:
        end = at + kind.length(data[at])
        if end > len(data):
            continue
        try:
            found = decode_special(bytes(data[at:end]), (kind,))
        except ValueError:
            continue
        return Found(at, end, kind, found.value)
    return None


def replaced_frames(counter_before: int, counter_after: int, counter_step: int) -> int:
    """Normal-mode datagrams an answer took the place of: the counter gap across it, less one.

    The counter counts internal samples (§7.5.2.2.18, p. 55), so the gap says how many
    datagrams' time the answer took; an unchanged counter is a whole wrap (256 / step), as
    the frame decoder reads it, so the two agree on every gap.
    """
    gap = (int(counter_after) - int(counter_before)) % 256 or 256
    return gap // counter_step - 1


def find_configuration(data: bytes) -> UnitConfiguration | None:
    """The first configuration datagram in a stream whose CRC checks, if any."""
    found = locate_special(data, (CONFIGURATION,))
    return found.value if found is not None and isinstance(found.value, UnitConfiguration) else None


def cut_specials(data: bytes | bytearray) -> tuple[bytes, list[Found], int]:
    """(``data`` without its start-up datagrams, those found in order, where an incomplete one
    may begin in what is left: the bytes from there on may still complete one)."""
    found: list[Found] = []
    kept = bytearray()
    at = 0
    while (hit := locate_special(data, START_UP, at)) is not None:
        kept += data[at:hit.start]
        found.append(hit)
        at = hit.end
    kept += data[at:]
    ids = [i for k in START_UP for i in k.identifiers]
    tail = np.frombuffer(bytes(kept[-_LONGEST:]), dtype=np.uint8)
    partial = len(kept)
    for offset in np.flatnonzero(np.isin(tail, ids)).tolist():
        position = len(kept) - len(tail) + offset
        kind = next(k for k in START_UP if kept[position] in k.identifiers)
        if position + kind.length(kept[position]) > len(kept):
            partial = position
            break
    return bytes(kept), found, partial
