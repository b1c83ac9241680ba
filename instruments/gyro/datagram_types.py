"""STIM300 normal-mode datagram types and their byte layouts (TS1524 rev 31, §5.5.6).

The one place that knows which datagram carries what and where. A unit
sends the one type it is configured for (Table 5-21, p. 37): rate always,
plus any of acceleration, inclination, temperature and PPS. Whatever is
chosen is sent in the order of the full datagram (Table 5-20, p. 36):

    identifier · gyro x, y, z (3 × 24 bit) · gyro status
    [acc x, y, z · acc status] [incl x, y, z · incl status]
    [temperatures of each cluster present: x, y, z (3 × 16 bit) · status]
    [PPS (24 bit) · PPS status] · counter · latency (16 bit) · CRC-32 [· CR LF]

Temperatures are sent only for the clusters in the datagram (text under
Table 5-20, p. 37). The CRC covers everything before it, padded with 0x00
dummy bytes to whole 32-bit words (§5.5.7, Table 5-22, p. 38); the padding
follows from the length, and the tests check it against Table 5-22 typed
entry by entry. CR LF, when configured, follows the CRC and is outside it.
The identifier byte does not change with CR LF for normal-mode datagrams;
only the configuration datagram has its own pair (0xBC / 0xBD, Table 5-16).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

#: internal sample rate the counter counts (§7.5.2.2.18, p. 55)
INTERNAL_RATE_HZ = 2000.0
#: accelerometer LSB per range in g (§7.5.2.2.7, Equation 3, p. 52)
ACCELEROMETER_LSB_G = {5: 2.0**-20, 10: 2.0**-19, 30: 2.0**-18, 80: 2.0**-16}
#: the standard accelerometer range (Table 5-1 note 1, p. 7; Table 5-16 byte 17 code 0)
DEFAULT_ACCELEROMETER_RANGE_G = 10
#: inclinometer LSB in g (§7.5.2.2.11, Equation 5, p. 53)
INCLINOMETER_LSB_G = 2.0**-22


@dataclass(frozen=True)
class DatagramType:
    """What a normal-mode datagram carries besides the rates (Table 5-21)."""

    identifier: int
    acceleration: bool = False
    inclination: bool = False
    temperature: bool = False
    pps: bool = False

    def describe(self) -> str:
        """``rate, acceleration, inclination`` (the words of Table 5-21)."""
        parts = ["rate"]
        parts += [name for name, on in (("acceleration", self.acceleration),
                                        ("inclination", self.inclination),
                                        ("temperature", self.temperature),
                                        ("PPS", self.pps)) if on]
        return ", ".join(parts)

    def label(self) -> str:
        """``0x93 (rate, acceleration, inclination)``."""
        return f"0x{self.identifier:02X} ({self.describe()})"


def _types() -> dict[int, DatagramType]:
    found = {}
    for pps, base in ((False, (0x90, 0x91, 0x92, 0x93, 0x94, 0xA5, 0xA6, 0xA7)),
                      (True, (0xF0, 0xF1, 0xF2, 0xF3, 0xF4, 0xF5, 0xF6, 0xF7))):
        for bits, identifier in enumerate(base):
            found[identifier] = DatagramType(identifier, acceleration=bool(bits & 1),
                                             inclination=bool(bits & 2),
                                             temperature=bool(bits & 4), pps=pps)
    return found


#: every normal-mode datagram of Table 5-21, by identifier
NORMAL_MODE_TYPES: dict[int, DatagramType] = _types()
ID_RATE = 0x90
ID_RATE_TEMP = 0x94


def datagram_type(identifier: int) -> DatagramType:
    """The type of ``identifier``; ``ValueError`` naming the known ones otherwise."""
    try:
        return NORMAL_MODE_TYPES[int(identifier)]
    except (KeyError, TypeError, ValueError):
        known = ", ".join(f"0x{i:02X}" for i in NORMAL_MODE_TYPES)
        raise ValueError(f"0x{int(identifier):02X} is not a STIM300 normal-mode datagram "
                         f"(TS1524 Table 5-21: {known})") from None


def parse_identifier(value: object) -> int:
    """A station's ``datagram:`` as an identifier: 147, ``0x93`` or ``"0x93"``."""
    if isinstance(value, bool):
        raise ValueError(f"expected a datagram identifier such as 0x93, got {value!r}")
    if isinstance(value, int):
        identifier = value
    elif isinstance(value, str):
        try:
            identifier = int(value.strip(), 0)
        except ValueError:
            raise ValueError(f"expected a datagram identifier such as 0x93, got {value!r}") from None
    else:
        raise ValueError(f"expected a datagram identifier such as 0x93, got {value!r}")
    return datagram_type(identifier).identifier


@dataclass(frozen=True)
class FrameLayout:
    """Byte offsets of one datagram type on the wire (None: not in this type)."""

    kind: DatagramType
    acc_offset: int | None
    acc_status_offset: int | None
    incl_offset: int | None
    incl_status_offset: int | None
    temp_offset: int | None              # gyro temperatures x, y, z
    temp_status_offset: int | None
    acc_temp_offset: int | None
    acc_temp_status_offset: int | None
    incl_temp_offset: int | None
    incl_temp_status_offset: int | None
    pps_offset: int | None
    pps_status_offset: int | None
    counter_offset: int
    latency_offset: int
    crc_offset: int
    crlf: bool = False

    @property
    def identifier(self) -> int:
        return self.kind.identifier

    @property
    def with_temperature(self) -> bool:
        return self.temp_offset is not None

    @property
    def length(self) -> int:
        """Bytes on the wire per datagram, terminator included."""
        return self.crc_offset + 4 + (2 if self.crlf else 0)

    @property
    def crc_dummy_bytes(self) -> int:
        """Zero bytes appended before the CRC is computed (to a multiple of 4)."""
        return -self.crc_offset % 4


RATE_OFFSET = 1
STATUS_OFFSET = 10


@cache
def layout_of(identifier: int, crlf: bool = False) -> FrameLayout:
    """The byte layout of normal-mode datagram ``identifier`` (see the module docstring)."""
    kind = datagram_type(identifier)
    at = STATUS_OFFSET + 1
    offsets: dict[str, int | None] = {}

    def field(name: str, present: bool, width: int) -> None:
        nonlocal at
        offsets[name] = at if present else None
        offsets[name + "_status"] = at + width if present else None
        at += (width + 1) if present else 0

    field("acc", kind.acceleration, 9)
    field("incl", kind.inclination, 9)
    field("temp", kind.temperature, 6)
    field("acc_temp", kind.temperature and kind.acceleration, 6)
    field("incl_temp", kind.temperature and kind.inclination, 6)
    field("pps", kind.pps, 3)
    return FrameLayout(
        kind,
        offsets["acc"], offsets["acc_status"], offsets["incl"], offsets["incl_status"],
        offsets["temp"], offsets["temp_status"], offsets["acc_temp"], offsets["acc_temp_status"],
        offsets["incl_temp"], offsets["incl_temp_status"], offsets["pps"], offsets["pps_status"],
        counter_offset=at, latency_offset=at + 1, crc_offset=at + 3, crlf=bool(crlf),
    )


LAYOUT_RATE = layout_of(ID_RATE)
LAYOUT_RATE_TEMP = layout_of(ID_RATE_TEMP)


def layout_for(with_temperature: bool, crlf: bool = False) -> FrameLayout:
    """0x94 with temperature, else 0x90 (the two types the station once knew)."""
    return layout_of(ID_RATE_TEMP if with_temperature else ID_RATE, bool(crlf))


# --------------------------------------------------------------------------- counter rule


def counter_step(sample_rate_hz: float) -> int:
    """Counter ticks per datagram at ``sample_rate_hz`` (§7.5.2.2.18, p. 55).

    The counter counts the unit's internal 2000 Hz samples, so at 125 Hz it
    advances 16 per datagram. For rates a STIM300 cannot be set to (the
    simulator accepts any), the nearest whole number of ticks, at least 1.
    """
    if not sample_rate_hz > 0:
        raise ValueError(f"sample_rate_hz must be > 0, got {sample_rate_hz!r}")
    return max(1, round(INTERNAL_RATE_HZ / float(sample_rate_hz)))


def counter_values(frame_index, step: int):
    """Counter byte of datagrams ``frame_index`` (numpy int array) at ``step`` ticks each."""
    return (frame_index * int(step)) & 0xFF


@cache
def frames_per_counter_step(step: int) -> tuple[int, ...]:
    """For each 8-bit counter difference d, how many datagrams it spans (a 256-entry table).

    The smallest n ≥ 1 with n·step ≡ d (mod 256). A difference no whole
    number of datagrams can give (the counter re-phased, e.g. a reset) is
    read as the nearest whole number of datagrams, at least one.
    """
    table = [0] * 256
    for n in range(256, 0, -1):
        table[(n * step) % 256] = n
    for d in range(256):
        if table[d] == 0:
            table[d] = max(1, round((d or 256) / step))
    return tuple(table)
