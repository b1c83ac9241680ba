"""The simulated STIM300's Part Number and Serial Number datagrams, typed from TS1524.

Built byte by byte from the "Specification" column of Table 5-13 (p. 29) and
Table 5-15 (p. 30) — the nibble each digit sits in, as the table words it —
not by inverting the driver's decoder (instruments/gyro/special_datagrams.py,
which reads the P-index column and Table 5-14). The CRC is the datasheet's
(§5.5.7, p. 37) over the 16 bytes before it, no dummy bytes (Table 5-22, p. 38).

A unit answers ``N<CR>`` and ``I<CR>`` with them (§8.1, §8.2, p. 58) and sends
them, with its configuration datagram, when it starts (§7.5.1, p. 47).
"""

from __future__ import annotations

import re

from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2

#: the simulated unit's part number (made up, in the datasheet's 5-7-3 form; the 13th and
#: 15th characters are letters beyond F, which take two nibbles, Table 5-14)
SIM_PART_NUMBER = "84167-0000000-S0M"
SIM_REVISION = "G"          # as its configuration datagram's byte 1 (stim_configuration.py)
#: what Table 5-15 can carry: the letter N and fourteen BCD digits
_SERIAL_FORM = re.compile(r"N\d{14}")
_DASH = 0x2D


def carries_serial(serial: str | None) -> bool:
    """Whether a Serial Number datagram can say ``serial`` (a unit's serial has this form)."""
    return serial is not None and _SERIAL_FORM.fullmatch(serial) is not None


def _value(char: str) -> int:
    """Table 5-14 read backwards for one character: '0'–'9' → 0–9, 'A'–'Z' → 10–35."""
    return ord(char) - (48 if char.isdigit() else 55)


def _framed(body: bytes, crlf: bool) -> bytes:
    return body + crc32_mpeg2(body).to_bytes(4, "big") + (b"\r\n" if crlf else b"")


def part_number_datagram(part_number: str, revision: str, crlf: bool) -> bytes:
    """Table 5-13: 20 bytes (22 with CR LF) for ``ddddd-ddddddd-ddd``."""
    head, middle, tail = part_number.split("-")
    d = [0] + [_value(c) for c in head + middle + tail]      # d[1] … d[15]
    body = bytes([
        0xB3 if crlf else 0xB1,                 # byte 0: identifier
        d[1],                                   # byte 1: low nibble 1st digit
        d[2] << 4 | d[3],                       # byte 2: 2nd, 3rd
        d[4] << 4 | d[5],                       # byte 3: 4th, 5th
        _DASH,                                  # byte 4: '-'
        d[6] << 4 | d[7],                       # byte 5: 6th, 7th
        d[8] << 4 | d[9],                       # byte 6: 8th, 9th
        d[10] << 4 | d[11],                     # byte 7: 10th, 11th
        _DASH,                                  # byte 8: '-'
        (d[13] & 0x0F) << 4 | d[14],            # byte 9: 13th (least significant nibble), 14th
        (d[15] & 0x0F) << 4 | d[15] >> 4,       # byte 10: 15th least, 15th most significant
        (d[13] >> 4) << 4 | d[12],              # byte 11: 13th most significant, 12th
        0, 0, 0,                                # bytes 12–14: for future use
        ord(revision),                          # byte 15: revision character
    ])
    return _framed(body, crlf)


def serial_number_datagram(serial: str, crlf: bool) -> bytes:
    """Table 5-15: 20 bytes (22 with CR LF) for ``N`` and fourteen digits."""
    if not carries_serial(serial):
        raise ValueError(f"serial {serial!r}: a Serial Number datagram carries N and 14 digits")
    digits = [int(c) for c in serial[1:]]
    pairs = [digits[i] << 4 | digits[i + 1] for i in range(0, 14, 2)]   # bytes 2–8, BCD
    body = bytes([0xB7 if crlf else 0xB5, ord("N"), *pairs, 0, 0, 0, 0, 0, 0, 0])
    return _framed(body, crlf)
