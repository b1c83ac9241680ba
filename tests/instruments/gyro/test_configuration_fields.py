"""The configuration datagram's fields a calibration relies on, typed from TS1524 rev 31 Table 5-16.

Every byte string here is written bit field by bit field from Table 5-16
(bytes 0–6 p. 31, bytes 7–13 p. 32, bytes 14–27 p. 33); the CRC comes from
the bit-by-bit reference in tests/support (§5.5.7 p. 37, 2 dummy bytes per
Table 5-22 p. 38). Nothing is built with the code under test.
"""

from __future__ import annotations

import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc

from gyrocal.instruments.gyro.configuration import GyroOutputUnit, decode_configuration


def typed(body: list[int], crlf: bool = False) -> bytes:
    assert len(body) == 22
    data = bytes(body)
    return data + bitwise_crc(data + bytes(2)).to_bytes(4, "big") + (b"\r\n" if crlf else b"")


# A unit as shipped for rate output: rev 'C', firmware 12, 2000 samples/s, temperature in the
# datagram (so 0x94), 921600 bit/s, x y z gyros active, angular rate, filters 262/262/262 Hz.
RATE_UNIT = [
    0xBC, ord("C"), 12,
    0b100_0_1_0_0_0,      # byte 3: 2000 samples/s, no PPS, temperature, no incl, no acc, no CR LF
    0b0010_0_00_0,        # byte 4: 921600 bit/s, 1 stop bit, parity none, line termination off
    0b0_1_1_1_0000,       # byte 5: gyro x, y, z active; output unit 0000 = angular rate
    0b0_100_0_100,        # byte 6: gyro filter x = 262 Hz, y = 262 Hz
    0b0_100_0000,         # byte 7: gyro filter z = 262 Hz; g-comp OFF
    0b0_1_1_1_0000,       # byte 8: accelerometers x, y, z active; acceleration [g]
    0b0_011_0_011,        # byte 9: accelerometer filter x = 131 Hz, y = 131 Hz
    0b0_011_0000,         # byte 10: accelerometer filter z = 131 Hz
    0b0_1_1_1_0000,       # byte 11: inclinometers active, acceleration [g]
    0b0_000_0_000,        # byte 12: inclinometer filters 16 Hz
    0b0_000_0000,         # byte 13: inclinometer filter z 16 Hz, PPS filtered
    0b0000_1_000,         # byte 14: PPS input
    0x00, 0x00,           # bytes 15–16: gyro range x, y / z: code 0 = 400 °/s
    0x00, 0x00,           # bytes 17–18: accelerometer range 10 g on x, y / z
    0x00, 0x00,           # bytes 19–20: inclinometer range 1.7 g
    0b0000_0_0_0_0,       # byte 21: TOV 5 V, no toggling, no bias trim at start-up
]


def test_a_rate_unit_decodes_every_field_a_calibration_relies_on():
    config = decode_configuration(typed(RATE_UNIT))
    assert (config.revision, config.firmware, config.sample_rate_hz) == ("C", 12, 2000.0)
    assert (config.datagram, config.crlf, config.bit_rate) == (0x94, False, 921600)
    assert config.gyro_output_unit is GyroOutputUnit.ANGULAR_RATE
    assert config.gyro_axes_active == (True, True, True)
    assert config.gyro_filter_hz == (262, 262, 262)
    assert config.gyro_g_compensation_code == 0
    assert config.gyro_range_dps == (400, 400, 400)
    assert config.accelerometer_axes_active == (True, True, True)
    assert config.accelerometer_output_code == 0
    assert config.accelerometer_filter_hz == (131, 131, 131)
    assert config.accelerometer_range_g == (10, 10, 10)
    assert (config.stop_bits, config.parity) == (1, "none")
    assert "angular rate [°/s]" in config.describe()


# Table 5-16 byte 5 bits 3–0 (p. 31), each code typed with its name.
OUTPUT_CODES = {
    0b0000: GyroOutputUnit.ANGULAR_RATE,
    0b0001: GyroOutputUnit.INCREMENTAL_ANGLE,
    0b0010: GyroOutputUnit.AVERAGE_ANGULAR_RATE,
    0b0011: GyroOutputUnit.INTEGRATED_ANGLE,
    0b1000: GyroOutputUnit.ANGULAR_RATE_DELAYED,
    0b1001: GyroOutputUnit.INCREMENTAL_ANGLE_DELAYED,
    0b1010: GyroOutputUnit.AVERAGE_ANGULAR_RATE_DELAYED,
    0b1011: GyroOutputUnit.INTEGRATED_ANGLE_DELAYED,
}


@pytest.mark.parametrize("code", sorted(OUTPUT_CODES))
def test_the_gyro_output_unit_of_byte_5(code):
    body = list(RATE_UNIT)
    body[5] = 0b0_1_1_1_0000 | code
    config = decode_configuration(typed(body))
    assert config.gyro_output_unit is OUTPUT_CODES[code]
    assert config.gyro_output_code == code
    assert config.gyro_axes_active == (True, True, True)      # the high bits untouched


def test_an_unlisted_output_code_is_kept_and_named_not_guessed():
    body = list(RATE_UNIT)
    body[5] = 0b0_1_1_1_0101                                    # 0101: not in Table 5-16
    config = decode_configuration(typed(body))
    assert config.gyro_output_unit is None and config.gyro_output_code == 5
    assert "code 0x5 (not listed in TS1524 Table 5-16)" in config.describe()


@pytest.mark.parametrize(("byte5", "axes"), [
    (0b0_1_0_0_0000, (True, False, False)),       # only x active
    (0b0_0_1_0_0000, (False, True, False)),       # only y
    (0b0_0_0_1_0000, (False, False, True)),       # only z
    (0b0_0_0_0_0001, (False, False, False)),      # none (and incremental angle)
])
def test_the_active_gyro_axes_of_byte_5(byte5, axes):
    body = list(RATE_UNIT)
    body[5] = byte5
    assert decode_configuration(typed(body)).gyro_axes_active == axes


def test_filters_ranges_and_line_settings_per_axis():
    body = list(RATE_UNIT)
    body[4] = 0b0001_1_01_1       # 460800 bit/s, 2 stop bits, parity even, termination on
    body[6] = 0b0_000_0_001       # gyro filter x 16 Hz, y 33 Hz
    body[7] = 0b0_010_0111        # gyro filter z 66 Hz; g-comp bias ACC, scale ACC (0111)
    body[8] = 0b0_1_0_1_0001      # accelerometers x, z active; incremental velocity
    body[9] = 0b0_100_0_010       # accelerometer filter x 262 Hz, y 66 Hz
    body[10] = 0b0_001_0000       # accelerometer filter z 33 Hz
    body[17] = 0b0011_0100        # accelerometer range x 5 g, y 30 g
    body[18] = 0b0110_0000        # accelerometer range z 80 g
    config = decode_configuration(typed(body))
    assert (config.bit_rate, config.stop_bits, config.parity) == (460800, 2, "even")
    assert config.gyro_filter_hz == (16, 33, 66)
    assert config.gyro_g_compensation_code == 0b0111
    assert config.accelerometer_axes_active == (True, False, True)
    assert config.accelerometer_output_code == 1
    assert config.accelerometer_filter_hz == (262, 66, 33)
    assert config.accelerometer_range_g == (5, 30, 80)


@pytest.mark.parametrize(("byte3", "rate_hz", "identifier"), [
    (0b000_0_0_0_0_0, 125.0, 0x90),     # 125 samples/s, rate only
    (0b001_0_0_1_0_0, 250.0, 0x92),     # 250, inclination
    (0b010_0_1_0_1_0, 500.0, 0xA5),     # 500, temperature + acceleration
    (0b011_1_0_0_0_0, 1000.0, 0xF0),    # 1000, PPS
    (0b100_0_1_1_1_0, 2000.0, 0xA7),    # 2000, temperature + inclination + acceleration
    (0b101_0_0_0_1_0, None, 0x91),      # external trigger, acceleration
])
def test_byte_3_sample_rate_and_content(byte3, rate_hz, identifier):
    body = list(RATE_UNIT)
    body[3] = byte3
    config = decode_configuration(typed(body))
    assert (config.sample_rate_hz, config.datagram) == (rate_hz, identifier)
