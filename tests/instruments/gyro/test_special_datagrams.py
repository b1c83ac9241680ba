"""The STIM300's special datagrams decoded from bytes typed from TS1524 rev 31.

Part Number: Table 5-13 and Table 5-14 (p. 29); Serial Number: Table 5-15
(p. 30); Bias Trim Offset: Table 5-17 (p. 34); dummy bytes for the CRC:
Table 5-22 (p. 38). The example unit is the one §8.7 lists entering Service
Mode (Figure 8-1, p. 60): serial N25582405002002, part number
84167-4400003-321 rev K. The CRC is computed bit by bit here (tests/support/
crc_reference.py), never by the code under test. The simulator's own encoding
(instruments/sim/stim_identity.py) is checked against the same typed bytes.
"""

from __future__ import annotations

import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc
from stim300_bytes import PART_BODY, SERIAL_BODY

from gyrocal.instruments.gyro.special_datagrams import (
    BiasTrimOffset,
    PartNumber,
    SerialNumber,
    cut_specials,
    decode_special,
    locate_special,
)
from gyrocal.instruments.sim.stim_identity import part_number_datagram, serial_number_datagram


def framed(body: bytes, crlf: bool = False) -> bytes:
    return body + bitwise_crc(body).to_bytes(4, "big") + (b"\r\n" if crlf else b"")


def test_the_serial_number_datagram_of_the_example_unit():
    found = decode_special(framed(SERIAL_BODY))
    assert found.kind.name == "serial number"
    assert found.value == SerialNumber("N25582405002002")
    assert len(framed(SERIAL_BODY)) == 20                     # bytes 0-19 (Table 5-15)
    crlf = framed(bytes([0xB7]) + SERIAL_BODY[1:], crlf=True)  # 0xB7: with CR LF, 22 bytes
    assert decode_special(crlf).value == SerialNumber("N25582405002002")


def test_the_part_number_datagram_of_the_example_unit():
    found = decode_special(framed(PART_BODY))
    assert found.value == PartNumber("84167-4400003-321", "K")
    assert found.value.describe() == "part number 84167-4400003-321 rev K"


def test_part_number_letters_past_f_take_two_nibbles():
    # Table 5-14: digit 13 = P12 + 16·P16, digit 15 = P14 + 16·P15; value ≥ 10 → value + 55.
    # 'S' = 28 = 0x1C: byte 9 high C, byte 11 high 1; 'M' = 22 = 0x16: byte 10 high 6, low 1
    body = bytes([0xB1, 0x08, 0x41, 0x67, 0x2D, 0x00, 0x00, 0x00, 0x2D, 0xC0, 0x61, 0x10,
                  0, 0, 0, ord("G")])
    assert decode_special(framed(body)).value == PartNumber("84167-0000000-S0M", "G")


def test_the_simulator_builds_the_same_bytes_as_the_tables():
    assert serial_number_datagram("N25582405002002", crlf=False) == framed(SERIAL_BODY)
    assert part_number_datagram("84167-4400003-321", "K", crlf=False) == framed(PART_BODY)
    assert part_number_datagram("84167-4400003-321", "K", crlf=True)[-2:] == b"\r\n"
    with pytest.raises(ValueError, match="N and 14 digits"):
        serial_number_datagram("SIM-0001", crlf=False)


def test_a_bias_trim_offset_datagram():
    # Table 5-17: 0xD1, nine 24-bit two's complement offsets (gyro x = +1 °/s = 2^14 LSB,
    # §7.5.2.2.2; gyro y = -1 LSB), reference 0x01020304, 7 saves left, 2 spare
    offsets = [1 << 14, -1, 0, 5, 0, 0, 0, 0, -7]
    body = bytes([0xD1]) + b"".join(v.to_bytes(3, "big", signed=True) for v in offsets)
    body += bytes([1, 2, 3, 4, 0, 7, 0, 0])
    found = decode_special(framed(body))
    assert found.value == BiasTrimOffset((1.0, -1.0 / 16384, 0.0), (5, 0, 0), (0, 0, -7),
                                         0x01020304, 7)


def test_a_wrong_crc_or_a_serial_without_n_is_refused():
    bad = bytearray(framed(SERIAL_BODY))
    bad[5] ^= 0x01
    with pytest.raises(ValueError, match="CRC"):
        decode_special(bytes(bad))
    with pytest.raises(ValueError, match="'N'"):
        decode_special(framed(bytes([0xB5, 0x4D]) + SERIAL_BODY[2:]))
    assert locate_special(bytes(bad)) is None


def test_start_up_datagrams_are_cut_from_a_stream_and_a_partial_one_is_marked():
    frames = bytes([0x90]) * 40          # not a special datagram's identifier
    stream = framed(PART_BODY) + framed(SERIAL_BODY) + frames
    kept, found, partial = cut_specials(stream)
    assert kept == frames and partial == len(frames)
    assert [f.kind.name for f in found] == ["part number", "serial number"]
    kept, found, partial = cut_specials(frames + framed(PART_BODY)[:12])
    assert found == [] and partial == len(frames)    # the tail may still become a datagram
