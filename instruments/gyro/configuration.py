"""The STIM300 configuration datagram (0xBC, or 0xBD with CR LF): rate, content, ranges.

A unit sends it on request and, as configured, at start-up (TS1524 §5.5.3,
Table 5-16, pp. 31–33). It is the unit's own statement of what a station
file must declare: the normal-mode datagram (byte 3's content bits select
the Table 5-21 identifier), the sample rate (byte 3 bits 7–5), the bit
rate (byte 4) and the accelerometer range per axis (bytes 17–18). 22 bytes
precede the CRC, which is computed with 2 dummy bytes (Table 5-22, p. 38).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2
from gyrocal.instruments.gyro.datagram_types import NORMAL_MODE_TYPES

ID_CONFIGURATION = 0xBC
ID_CONFIGURATION_CRLF = 0xBD
CONFIGURATION_BODY_BYTES = 22          # identifier .. byte 21 (Table 5-16)
CONFIGURATION_DUMMY_BYTES = 2          # Table 5-22

#: byte 3 bits 7–5 → samples/s (None: external trigger)
SAMPLE_RATE_CODES = {0: 125.0, 1: 250.0, 2: 500.0, 3: 1000.0, 4: 2000.0, 5: None}
#: byte 4 bits 7–4 → bits/s (None: user-defined)
BIT_RATE_CODES = {0: 374400, 1: 460800, 2: 921600, 3: 1843200, 15: None}
#: accelerometer range nibble (bytes 17–18) → g
ACCELEROMETER_RANGE_CODES = {0: 10, 3: 5, 4: 30, 6: 80}


@dataclass(frozen=True)
class UnitConfiguration:
    """What the unit says about itself."""

    revision: str                     # part number revision character
    firmware: int
    sample_rate_hz: float | None      # None: external trigger
    datagram: int                     # the normal-mode identifier byte 3 selects
    crlf: bool
    bit_rate: int | None              # None: user-defined
    accelerometer_range_g: tuple[int | None, int | None, int | None]


def configuration_length(crlf: bool) -> int:
    return CONFIGURATION_BODY_BYTES + 4 + (2 if crlf else 0)


def decode_configuration(frame: bytes) -> UnitConfiguration:
    """Decode one configuration datagram; ``ValueError`` if its identifier or CRC is wrong."""
    if not frame or frame[0] not in (ID_CONFIGURATION, ID_CONFIGURATION_CRLF):
        raise ValueError("not a configuration datagram (identifier 0xBC / 0xBD)")
    crlf = frame[0] == ID_CONFIGURATION_CRLF
    if len(frame) != configuration_length(crlf):
        raise ValueError(f"a configuration datagram is {configuration_length(crlf)} bytes, got {len(frame)}")
    body = frame[:CONFIGURATION_BODY_BYTES]
    stored = int.from_bytes(frame[CONFIGURATION_BODY_BYTES:CONFIGURATION_BODY_BYTES + 4], "big")
    if crc32_mpeg2(body + bytes(CONFIGURATION_DUMMY_BYTES)) != stored:
        raise ValueError("configuration datagram: CRC does not check")
    content = frame[3]
    flags = (bool(content & 0x02), bool(content & 0x04), bool(content & 0x08), bool(content & 0x10))
    identifier = next(i for i, t in NORMAL_MODE_TYPES.items()
                      if (t.acceleration, t.inclination, t.temperature, t.pps) == flags)
    ranges = (frame[17] >> 4, frame[17] & 0x0F, frame[18] >> 4)
    return UnitConfiguration(
        revision=chr(frame[1]), firmware=frame[2],
        sample_rate_hz=SAMPLE_RATE_CODES.get(content >> 5),
        datagram=identifier, crlf=bool(content & 0x01),
        bit_rate=BIT_RATE_CODES.get(frame[4] >> 4),
        accelerometer_range_g=tuple(ACCELEROMETER_RANGE_CODES.get(code) for code in ranges),
    )


def find_configuration(data: bytes) -> UnitConfiguration | None:
    """The first configuration datagram in a stream whose CRC checks, if any."""
    buf = np.frombuffer(data, dtype=np.uint8)
    for start in np.flatnonzero((buf == ID_CONFIGURATION) | (buf == ID_CONFIGURATION_CRLF)).tolist():
        length = configuration_length(data[start] == ID_CONFIGURATION_CRLF)
        try:
            return decode_configuration(data[start:start + length])
        except ValueError:
            continue
    return None
