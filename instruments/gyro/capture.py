"""A recorded gyro byte stream from a file: raw binary, or one decimal number per byte.

Two forms exist in the field: the bytes exactly as read from the serial
line (``cat /dev/ttyUSB0 > capture.bin``), and a text dump with each byte
written as a decimal number separated by white space (the form of the UBC
Rocket team's public STIM300 captures, repository UBC-Rocket/Whistler-
Blackcomb-v2, ``data/imu/``). A file made only of digits and white space
(or commas), give or take a stray character, is read as the text form: a
binary STIM300 stream cannot be, since its datagrams are mostly other bytes.
"""

from __future__ import annotations

import os
import re

import numpy as np

from gyrocal.inputs import InputError, open_regular_file

_TEXT_BYTES = frozenset(b"0123456789 \t\r\n,")
_TOKEN = re.compile(rb"[0-9]+")


def read_capture(path: str | os.PathLike[str]) -> bytes:
    """The captured bytes; :class:`InputError` naming the file (and line) when unreadable."""
    display = os.fspath(path)
    fd = open_regular_file(path, display)
    try:
        with os.fdopen(fd, "rb") as handle:
            data = handle.read()
    except OSError as error:
        raise InputError.one(display, f"cannot read the file: {error.strerror or error}") from None
    if not data:
        raise InputError.one(display, "empty capture: no bytes")
    if _is_decimal_text(data):
        return _decimal_text_bytes(data, display)
    return data


def _is_decimal_text(data: bytes) -> bool:
    """Mostly digits and separators (a stray character is then an error, not binary)."""
    head = data[: 1 << 16]
    text_like = sum(head.count(b) for b in _TEXT_BYTES)
    return any(48 <= b <= 57 for b in head) and text_like >= 0.9 * len(head)


def _decimal_text_bytes(data: bytes, display: str) -> bytes:
    """``147 120 0 …`` → bytes; a value above 255 or a stray character is named by line."""
    if not set(data) <= _TEXT_BYTES:
        bad = next(i for i, b in enumerate(data) if b not in _TEXT_BYTES)
        raise InputError.one(display, "not a byte capture: a character other than digits, "
                             "spaces or commas in a decimal capture", data.count(b"\n", 0, bad) + 1)
    tokens = _TOKEN.findall(data)
    numbers = np.array([int(v) if len(v) < 5 else 256 for v in tokens], dtype=np.int64)
    over = np.flatnonzero(numbers > 255)
    if over.size:
        token = over[0]
        match = list(_TOKEN.finditer(data))[token]
        raise InputError.one(display, f"value {match.group().decode()} (number {token + 1}) is not a "
                             "byte (0..255)", data.count(b"\n", 0, match.start()) + 1)
    return numbers.astype(np.uint8).tobytes()
