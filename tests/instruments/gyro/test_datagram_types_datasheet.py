"""Every STIM300 normal-mode datagram and the configuration datagram, typed from TS1524 rev 31.

Sources (STIM300 datasheet TS1524 rev 31): Table 5-20 (p. 36) field order
of the full datagram; Table 5-21 (p. 37) identifiers and content; Table
5-22 (p. 38) CRC dummy bytes per identifier; §5.5.7 (p. 37) CRC rule;
§7.5.2.2.2/7/11/17 (pp. 49–55) LSBs: rate 2^-14 °/s, acceleration
2^-20/2^-19/2^-18/2^-16 g for 5/10/30/80 g, inclination 2^-22 g, temperature
1/256 °C; Table 5-16 (pp. 31–33) configuration datagram. Expected bytes are
written here field by field (and one real unit's datagram is typed out
whole); the CRC comes from the bit-by-bit reference in tests/support.
"""

from __future__ import annotations

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc
from stim300_bytes import hand_configuration

from gyrocal.instruments.gyro.channels import SensorChannels
from gyrocal.instruments.gyro.configuration import decode_configuration
from gyrocal.instruments.gyro.datagram import FrameDecoder, encode_frame_array
from gyrocal.instruments.gyro.datagram_types import (
    NORMAL_MODE_TYPES,
    counter_step,
    datagram_type,
    frames_per_counter_step,
    layout_of,
)
from gyrocal.instruments.gyro.special_datagrams import find_configuration
from gyrocal.instruments.gyro.survey import survey_stream

# Table 5-21: identifier → content, typed.
TABLE_5_21 = {
    0x90: "rate", 0x91: "rate, acceleration", 0x92: "rate, inclination",
    0x93: "rate, acceleration, inclination", 0x94: "rate, temperature",
    0xA5: "rate, acceleration, temperature", 0xA6: "rate, inclination, temperature",
    0xA7: "rate, acceleration, inclination, temperature",
    0xF0: "rate, PPS", 0xF1: "rate, acceleration, PPS", 0xF2: "rate, inclination, PPS",
    0xF3: "rate, acceleration, inclination, PPS", 0xF4: "rate, temperature, PPS",
    0xF5: "rate, acceleration, temperature, PPS", 0xF6: "rate, inclination, temperature, PPS",
    0xF7: "rate, acceleration, inclination, temperature, PPS",
}
# Table 5-22: identifier → dummy bytes for the CRC, typed.
TABLE_5_22 = {0x90: 2, 0x91: 0, 0x92: 0, 0x93: 2, 0x94: 3, 0xA5: 2, 0xA6: 2, 0xA7: 1,
              0xF0: 2, 0xF1: 0, 0xF2: 0, 0xF3: 2, 0xF4: 3, 0xF5: 2, 0xF6: 2, 0xF7: 1}
ACC_LSB_10G = 2.0**-19
INCL_LSB = 2.0**-22

RATE_RAW = (0x012345, -0x000102, 0x7FFFFF)          # x, y, z
ACC_RAW = (0x080000, -0x00ABCD, 0x000001)
INCL_RAW = (0x400000, -0x000010, 0x003000)
GYRO_T_RAW, ACC_T_RAW, INCL_T_RAW = (0x1980, 0x1A00, -0x0100), (0x1900, 0x1901, 0x1902), (0x0A00, 0, -1)
PPS_RAW = 0x0186A0                                   # 100 000 µs
COUNTER, LATENCY_US = 0xC8, 0x01FA


def s24(v: int) -> bytes:
    return (v & 0xFFFFFF).to_bytes(3, "big")


def s16(v: int) -> bytes:
    return (v & 0xFFFF).to_bytes(2, "big")


def hand_datagram(identifier: int, crlf: bool = False) -> bytes:
    """Table 5-20's fields in order, those of ``identifier``'s Table 5-21 content only."""
    content = TABLE_5_21[identifier].split(", ")
    acc, incl, temp, pps = ("acceleration" in content, "inclination" in content,
                            "temperature" in content, "PPS" in content)
    body = bytes([identifier]) + b"".join(map(s24, RATE_RAW)) + bytes([0x00])
    if acc:
        body += b"".join(map(s24, ACC_RAW)) + bytes([0x00])
    if incl:
        body += b"".join(map(s24, INCL_RAW)) + bytes([0x00])
    if temp:
        body += b"".join(map(s16, GYRO_T_RAW)) + bytes([0x00])
        if acc:
            body += b"".join(map(s16, ACC_T_RAW)) + bytes([0x00])
        if incl:
            body += b"".join(map(s16, INCL_T_RAW)) + bytes([0x00])
    if pps:
        body += s24(PPS_RAW) + bytes([0x00])
    body += bytes([COUNTER]) + LATENCY_US.to_bytes(2, "big")
    crc = bitwise_crc(body + bytes(TABLE_5_22[identifier]))
    return body + crc.to_bytes(4, "big") + (b"\r\n" if crlf else b"")


def test_table_5_21_identifiers_and_content():
    assert set(NORMAL_MODE_TYPES) == set(TABLE_5_21)
    for identifier, content in TABLE_5_21.items():
        assert datagram_type(identifier).describe() == content


@pytest.mark.parametrize("identifier", sorted(TABLE_5_22))
def test_table_5_22_dummy_bytes_follow_from_the_layout(identifier):
    layout = layout_of(identifier)
    assert layout.crc_dummy_bytes == TABLE_5_22[identifier]
    assert layout.length == len(hand_datagram(identifier))


def test_the_datasheet_example_a7_has_55_bytes_before_the_crc():
    """§5.5.7 (p. 37): 0xA7 has 55 bytes before the CRC, 13 words + 3 bytes, 1 dummy byte."""
    assert layout_of(0xA7).crc_offset == 55


@pytest.mark.parametrize("identifier", sorted(TABLE_5_21))
@pytest.mark.parametrize("crlf", [False, True])
def test_each_type_decodes_from_bytes_typed_field_by_field(identifier, crlf):
    data = hand_datagram(identifier, crlf) * 3
    decoded = FrameDecoder(datagram=identifier, crlf=crlf, accelerometer_range_g=10).feed(data)
    assert (len(decoded), decoded.crc_errors, decoded.garbage_bytes) == (3, 0, 0)
    assert np.array_equal(decoded.rate[0], np.array(RATE_RAW) * 2.0**-14)
    assert decoded.counter[0] == COUNTER and decoded.latency_us[0] == LATENCY_US
    channels = decoded.channels
    content = TABLE_5_21[identifier]
    assert (channels.acc_g is not None) == ("acceleration" in content)
    assert (channels.incl_g is not None) == ("inclination" in content)
    assert (decoded.temp_c is not None) == ("temperature" in content)
    if channels.acc_g is not None:
        assert np.array_equal(channels.acc_g[0], np.array(ACC_RAW) * ACC_LSB_10G)
    if channels.incl_g is not None:
        assert np.array_equal(channels.incl_g[0], np.array(INCL_RAW) * INCL_LSB)
    if decoded.temp_c is not None:
        assert np.array_equal(decoded.temp_c[0], np.array(GYRO_T_RAW) / 256)
        if channels.acc_g is not None:
            assert np.array_equal(channels.acc_temp_c[0], np.array(ACC_T_RAW) / 256)
        if channels.incl_g is not None:
            assert np.array_equal(channels.incl_temp_c[0], np.array(INCL_T_RAW) / 256)
    if "PPS" in content:
        assert channels.pps[0] == PPS_RAW
    else:
        assert channels.pps is None


@pytest.mark.parametrize("identifier", sorted(TABLE_5_21))
def test_each_type_encodes_to_the_typed_bytes(identifier):
    kind = datagram_type(identifier)
    channels = SensorChannels(
        acc_g=np.array([ACC_RAW]) * ACC_LSB_10G, incl_g=np.array([INCL_RAW]) * INCL_LSB,
        gyro_temp_c=np.array([GYRO_T_RAW]) / 256, acc_temp_c=np.array([ACC_T_RAW]) / 256,
        incl_temp_c=np.array([INCL_T_RAW]) / 256, pps=np.array([PPS_RAW]))
    frames = encode_frame_array(np.array([RATE_RAW]) * 2.0**-14, COUNTER, latency_us=LATENCY_US,
                                datagram=identifier, channels=channels, accelerometer_range_g=10,
                                temp_c=np.array([GYRO_T_RAW]) / 256 if kind.temperature else None)
    assert frames.tobytes() == hand_datagram(identifier)


# One datagram from a real unit, typed out whole (the first of UBC-Rocket/Whistler-Blackcomb-v2
# data/imu/imu_uart_data_3.txt): 0x93 with CR LF; its CRC is the unit's own.
REAL_0X93 = bytes([
    0x93, 0xFF, 0xFB, 0xDB, 0x00, 0x00, 0x7C, 0xFF, 0xFC, 0xC4, 0x00,     # id, rates, gyro status
    0x00, 0x05, 0xCE, 0x00, 0x01, 0xF6, 0x04, 0x0E, 0x54, 0x00,           # accelerometers, status
    0x00, 0x53, 0x9D, 0xFF, 0xB2, 0xB7, 0x40, 0x2D, 0x99, 0x00,           # inclinometers, status
    0x41, 0x01, 0xFB, 0x60, 0x73, 0xE3, 0xDE, 0x0D, 0x0A,                 # counter, latency, CRC, CR LF
])


def test_a_real_unit_datagram_decodes_and_reencodes_byte_for_byte():
    decoded = FrameDecoder(datagram=0x93, crlf=True, accelerometer_range_g=30).feed(REAL_0X93)
    assert len(decoded) == 1 and decoded.crc_errors == 0
    assert decoded.rate[0].tolist() == [-0x425 / 2**14, 0x7C / 2**14, -0x33C / 2**14]
    assert decoded.channels.acc_g[0].tolist() == [0x5CE / 2**18, 0x1F6 / 2**18, 0x040E54 / 2**18]
    assert decoded.channels.incl_g[0].tolist() == [0x539D / 2**22, -0x4D49 / 2**22, 0x402D99 / 2**22]
    assert (decoded.counter[0], decoded.latency_us[0]) == (0x41, 0x1FB)
    again = encode_frame_array(decoded.rate, decoded.counter, latency_us=decoded.latency_us,
                               crlf=True, datagram=0x93, channels=decoded.channels,
                               accelerometer_range_g=30)
    assert again.tobytes() == REAL_0X93


@pytest.mark.parametrize("fs_hz, step", [(2000, 1), (1000, 2), (500, 4), (250, 8), (125, 16)])
def test_counter_step_is_2000_over_fs(fs_hz, step):
    """§7.5.2.2.18 (p. 55): the counter counts 2000 Hz internal samples."""
    assert counter_step(fs_hz) == step
    table = frames_per_counter_step(step)
    assert table[step] == 1 and table[2 * step % 256] == 2 and table[0] == 256 // step


def test_a_counter_gap_at_125_hz_is_counted_in_datagrams():
    frames = np.concatenate([np.arange(0, 5), np.arange(7, 12)])           # datagrams 5, 6 lost
    data = encode_frame_array(np.zeros((10, 3)), (frames * 16) & 0xFF, datagram=0x90).tobytes()
    decoded = FrameDecoder(datagram=0x90, counter_step=16).feed(data)
    assert decoded.lost_frames == 2 and decoded.index.tolist() == frames.tolist()


@pytest.mark.parametrize("crlf", [False, True])
def test_configuration_datagram_typed_from_table_5_16(crlf):
    config = decode_configuration(hand_configuration(crlf))
    assert (config.revision, config.firmware, config.sample_rate_hz) == ("B", 7, 250.0)
    assert (config.datagram, config.crlf, config.bit_rate) == (0x93, crlf, 921600)
    assert config.accelerometer_range_g == (30, 30, 30)
    stream = b"\x00\x17" + hand_configuration(crlf) + hand_datagram(0x93)
    assert find_configuration(stream) == config
    corrupt = bytearray(hand_configuration(crlf))
    corrupt[5] ^= 1
    with pytest.raises(ValueError, match="CRC"):
        decode_configuration(bytes(corrupt))


@pytest.mark.parametrize("identifier", sorted(TABLE_5_21))
@pytest.mark.parametrize("crlf", [False, True])
def test_the_stream_survey_names_the_type_even_with_a_partial_last_datagram(identifier, crlf):
    stream = b"\x55\x00" + hand_datagram(identifier, crlf) * 5
    survey = survey_stream(stream[:-1])            # the last datagram one byte short
    assert survey.layout is not None
    assert (survey.layout.identifier, survey.layout.crlf) == (identifier, crlf)
    assert survey.frames_valid == 4
