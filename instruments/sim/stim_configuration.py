"""The simulated STIM300's answer to ``C<CR>``: a configuration datagram typed from TS1524 Table 5-16.

The bytes are put together here field by field from Table 5-16 (pp. 31–33),
with code tables of their own — not by inverting the driver's decoder
(instruments/gyro/configuration.py) — so a dry run checks one reading of
the table against another. The CRC is the datasheet's (§5.5.7, p. 37) over
the 22 bytes and 2 dummy bytes (Table 5-22, p. 38).

How many normal-mode datagrams the answer replaces (§8.3, p. 59: "may
replace more than one ... dependent on sampling-rate and bit-rate") is not
given as a rule; the simulator takes the slots that fall within the
answer's transmission time at 10 bits a character (unconfirmed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2

#: byte 3 bits 7–5 (p. 31), samples/s → code
_RATE_CODE = {125: 0b000, 250: 0b001, 500: 0b010, 1000: 0b011, 2000: 0b100}
#: byte 4 bits 7–4 (p. 31), bit/s → code; any other rate is "user-defined" (0b1111)
_BIT_RATE_CODE = {374400: 0b0000, 460800: 0b0001, 921600: 0b0010, 1843200: 0b0011}
_USER_BIT_RATE = 0b1111
#: bytes 17–18 nibbles (p. 33), g → code
_ACC_RANGE_CODE = {10: 0b0000, 5: 0b0011, 30: 0b0100, 80: 0b0110}
_FILTER_262_HZ = 0b100          # bytes 6–7, 9–10: the -3 dB frequency 262 Hz (pp. 31–32)
_BITS_PER_CHARACTER = 10        # start, 8 data, stop (byte 4: 1 stop bit, no parity)


@dataclass(frozen=True)
class SimUnitConfiguration:
    """What the simulated unit is configured for."""

    sample_rate_hz: float
    acceleration: bool          # what its normal-mode datagram carries (Table 5-21)
    inclination: bool
    temperature: bool
    pps: bool
    crlf: bool
    bit_rate: int
    accelerometer_range_g: int
    gyro_output_code: int = 0b0000      # byte 5 bits 3–0: angular rate [°/s]
    gyro_axes: str = "xyz"              # the active gyro axes (byte 5 bits 6–4)

    @property
    def answers(self) -> bool:
        """Table 5-16 has a code for this sample rate (a simulator may run at any rate;
        a unit configured so could not be, and the simulated one then does not answer)."""
        return self.sample_rate_hz in _RATE_CODE


def configuration_datagram(unit: SimUnitConfiguration) -> bytes:
    """The 26-byte datagram (28 with CR LF) the unit sends on ``C<CR>``."""
    byte3 = (_RATE_CODE[int(unit.sample_rate_hz)] << 5 | unit.pps << 4 | unit.temperature << 3
             | unit.inclination << 2 | unit.acceleration << 1 | unit.crlf)
    byte4 = _BIT_RATE_CODE.get(unit.bit_rate, _USER_BIT_RATE) << 4     # 1 stop bit, no parity, off
    axes = ("x" in unit.gyro_axes) << 6 | ("y" in unit.gyro_axes) << 5 | ("z" in unit.gyro_axes) << 4
    acc = _ACC_RANGE_CODE[unit.accelerometer_range_g]
    body = bytes([
        0xBD if unit.crlf else 0xBC,            # byte 0: identifier
        ord("G"), 20,                           # bytes 1–2: revision, firmware (made up)
        byte3, byte4,
        axes | unit.gyro_output_code,           # byte 5
        _FILTER_262_HZ << 4 | _FILTER_262_HZ,   # byte 6: gyro filters x, y
        _FILTER_262_HZ << 4,                    # byte 7: gyro filter z, g-comp off
        0b0111_0000,                            # byte 8: accelerometers x y z active, [g]
        _FILTER_262_HZ << 4 | _FILTER_262_HZ,   # byte 9
        _FILTER_262_HZ << 4,                    # byte 10
        0b0111_0000,                            # byte 11: inclinometers active, [g]
        _FILTER_262_HZ << 4 | _FILTER_262_HZ,   # byte 12
        _FILTER_262_HZ << 4,                    # byte 13: PPS filtered
        0b0000_0000,                            # byte 14: AUX input
        0x00, 0x00,                             # bytes 15–16: gyro range 400 °/s
        acc << 4 | acc, acc << 4,               # bytes 17–18: accelerometer ranges
        0x00, 0x00,                             # bytes 19–20: inclinometer range 1.7 g
        0x00,                                   # byte 21
    ])
    crc = crc32_mpeg2(body + bytes(2))
    return body + crc.to_bytes(4, "big") + (b"\r\n" if unit.crlf else b"")


def replaced_datagrams(answer_bytes: int, bit_rate: int, sample_rate_hz: float) -> int:
    """Normal-mode datagram slots the answer occupies: the one it replaces and those due
    before it has been sent (TS1524 Table 5-16 Note 1: a datagram due while another is
    still being sent is not sent)."""
    transmit_s = answer_bytes * _BITS_PER_CHARACTER / bit_rate
    return max(1, math.ceil(transmit_s * sample_rate_hz - 1e-9))
