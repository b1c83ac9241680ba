"""The STIM300 configuration datagram (0xBC, or 0xBD with CR LF): rate, content, units, ranges.

A unit sends it at start-up and on the ``C<CR>`` command (TS1524 §5.5.3,
Table 5-16, pp. 31–33; §8.3, Table 8-5, p. 59). It is the unit's own
statement of what a station file must declare, and of what the station
cannot declare but a calibration relies on:

* byte 3: sample rate (bits 7–5) and the normal-mode content bits, which
  select the Table 5-21 identifier, and CR LF (bit 0);
* byte 4: bit rate (bits 7–4), stop bits (bit 3), parity (bits 2–1);
* byte 5: which gyro axes are active (bits 6–4) and the gyro output unit
  (bits 3–0): angular rate, incremental angle, average angular rate,
  integrated angle, each optionally delayed. An angle read as a rate is a
  gross error no datagram shows, so the driver checks it (p. 31);
* bytes 6–7: the gyro low-pass filter per axis (x bits 6–4, y bits 2–0 of
  byte 6; z bits 6–4 of byte 7) and the g-compensation (byte 7 bits 3–0);
* byte 8: active accelerometer axes and their output unit; bytes 9–10 their
  filters (the same bit places as bytes 6–7) (p. 32);
* bytes 15–16: gyro range per axis (only code 0, ±400 °/s, is listed);
  bytes 17–18: accelerometer range per axis (p. 33).

22 bytes precede the CRC, which is computed with 2 dummy bytes (Table 5-22, p. 38).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

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
#: gyro range nibble (bytes 15–16) → °/s (Table 5-16 lists only code 0)
GYRO_RANGE_CODES = {0: 400}
#: low-pass filter code (3 bits, bytes 6–7 gyro, 9–10 accelerometers) → -3 dB frequency, Hz
FILTER_CODES = {0: 16, 1: 33, 2: 66, 3: 131, 4: 262}
#: byte 4 bits 2–1 → parity
PARITY_CODES = {0: "none", 1: "even", 2: "odd"}


class GyroOutputUnit(Enum):
    """Byte 5 bits 3–0: what the gyro fields of a normal-mode datagram hold (Table 5-16, p. 31)."""

    ANGULAR_RATE = 0x0
    INCREMENTAL_ANGLE = 0x1
    AVERAGE_ANGULAR_RATE = 0x2
    INTEGRATED_ANGLE = 0x3
    ANGULAR_RATE_DELAYED = 0x8
    INCREMENTAL_ANGLE_DELAYED = 0x9
    AVERAGE_ANGULAR_RATE_DELAYED = 0xA
    INTEGRATED_ANGLE_DELAYED = 0xB

    def label(self) -> str:
        """``angular rate [°/s]``, ``incremental angle [°], delayed``."""
        base = self.name.removesuffix("_DELAYED").lower().replace("_", " ")
        unit = "°" if "ANGLE" in self.name else "°/s"
        return f"{base} [{unit}]{', delayed' if self.name.endswith('_DELAYED') else ''}"


def output_unit_label(code: int) -> str:
    """The Table 5-16 name of a gyro output-unit code, or the code if it names none."""
    try:
        return GyroOutputUnit(code).label()
    except ValueError:
        return f"code 0x{code:X} (not listed in TS1524 Table 5-16)"


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
    gyro_output_code: int             # byte 5 bits 3–0 (see :class:`GyroOutputUnit`)
    gyro_axes_active: tuple[bool, ...]                 # x, y, z
    gyro_filter_hz: tuple[int | None, int | None, int | None]   # None: a code not listed
    gyro_g_compensation_code: int     # byte 7 bits 3–0
    gyro_range_dps: tuple[int | None, int | None, int | None]
    accelerometer_axes_active: tuple[bool, ...]
    accelerometer_output_code: int    # byte 8 bits 3–0 (0: acceleration [g])
    accelerometer_filter_hz: tuple[int | None, int | None, int | None]
    stop_bits: int
    parity: str

    @property
    def gyro_output_unit(self) -> GyroOutputUnit | None:
        """The output unit byte 5 names; None for a code Table 5-16 does not list."""
        try:
            return GyroOutputUnit(self.gyro_output_code)
        except ValueError:
            return None

    def describe(self) -> str:
        """One line for the journal and the station check."""
        axes = "".join(a for a, on in zip("xyz", self.gyro_axes_active, strict=True) if on) or "none"
        rate = "external trigger" if self.sample_rate_hz is None else f"{self.sample_rate_hz:g} samples/s"
        bits = "user-defined" if self.bit_rate is None else f"{self.bit_rate}"
        return (f"revision {self.revision}, firmware {self.firmware}, {rate}, datagram "
                f"0x{self.datagram:02X}{' with CR LF' if self.crlf else ''}, gyro output "
                f"{output_unit_label(self.gyro_output_code)}, gyro axes active {axes}, gyro "
                f"filters {_hz(self.gyro_filter_hz)}, gyro range ±{_list(self.gyro_range_dps)} °/s, "
                f"accelerometer range ±{_list(self.accelerometer_range_g)} g, bit rate {bits}, "
                f"{self.stop_bits} stop bit(s), parity {self.parity}")


def _list(values: tuple) -> str:
    return "/".join("?" if v is None else f"{v:g}" for v in values)


def _hz(values: tuple) -> str:
    return "/".join("?" if v is None else f"{v}" for v in values) + " Hz"


def _bits(byte: int, *shifts: int) -> tuple[bool, ...]:
    return tuple(bool(byte >> shift & 1) for shift in shifts)


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
    return UnitConfiguration(
        revision=chr(frame[1]), firmware=frame[2],
        sample_rate_hz=SAMPLE_RATE_CODES.get(content >> 5),
        datagram=identifier, crlf=bool(content & 0x01),
        bit_rate=BIT_RATE_CODES.get(frame[4] >> 4),
        accelerometer_range_g=_nibbles(frame[17], frame[18], ACCELEROMETER_RANGE_CODES),
        gyro_output_code=frame[5] & 0x0F,
        gyro_axes_active=_bits(frame[5], 6, 5, 4),
        gyro_filter_hz=_filters(frame[6], frame[7]),
        gyro_g_compensation_code=frame[7] & 0x0F,
        gyro_range_dps=_nibbles(frame[15], frame[16], GYRO_RANGE_CODES),
        accelerometer_axes_active=_bits(frame[8], 6, 5, 4),
        accelerometer_output_code=frame[8] & 0x0F,
        accelerometer_filter_hz=_filters(frame[9], frame[10]),
        stop_bits=2 if frame[4] & 0x08 else 1,
        parity=PARITY_CODES.get(frame[4] >> 1 & 0x03, "reserved"),
    )


def _nibbles(first: int, second: int, codes: dict[int, int]) -> tuple[int | None, int | None, int | None]:
    """x: high nibble of ``first``, y: its low nibble, z: high nibble of ``second``."""
    return (codes.get(first >> 4), codes.get(first & 0x0F), codes.get(second >> 4))


def _filters(first: int, second: int) -> tuple[int | None, int | None, int | None]:
    """x: bits 6–4 of ``first``, y: its bits 2–0, z: bits 6–4 of ``second`` (bytes 6–7, 9–10)."""
    return (FILTER_CODES.get(first >> 4 & 0x07), FILTER_CODES.get(first & 0x07),
            FILTER_CODES.get(second >> 4 & 0x07))
