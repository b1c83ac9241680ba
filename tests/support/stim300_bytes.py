"""STIM300 datagrams written byte by byte from the datasheet's datagram content tables.

Independent of ``gyrocal.instruments.gyro.datagram``: the tests' oracle for
the wire format. 0x90 (18 bytes): identifier, x/y/z rate (3 × 24-bit two's
complement), status, counter, 2-byte latency, CRC-32. 0x94 (25 bytes):
identifier, x/y/z rate, status, x/y/z temperature (3 × 16-bit two's
complement, 1/256 °C), temperature status, counter, latency, CRC-32. The
CRC covers the datagram padded with dummy 0x00 bytes to a multiple of 4
bytes (2 for 0x90, 3 for 0x94), computed by the bit-by-bit reference.

Special datagrams: the bodies of the Serial Number (Table 5-15, p. 30) and Part
Number (Tables 5-13/5-14, p. 29) datagrams of the unit in Figure 8-1 (p. 60), and a
configuration datagram (Table 5-16, pp. 31-33) field by field.
"""

from crc_reference import bitwise_crc32_mpeg2


def s24(value: int) -> bytes:
    return (value & 0xFFFFFF).to_bytes(3, "big")


def s16(value: int) -> bytes:
    return (value & 0xFFFF).to_bytes(2, "big")


def with_crc(body: bytes, dummy: int) -> bytes:
    """Append the CRC of ``body`` + ``dummy`` zero bytes (the datasheet's padding rule)."""
    assert (len(body) + dummy) % 4 == 0
    return body + bitwise_crc32_mpeg2(body + bytes(dummy)).to_bytes(4, "big")


def hand_frame_90(raw_xyz, status: int, counter: int, latency_us: int) -> bytes:
    body = bytes([0x90]) + b"".join(s24(r) for r in raw_xyz) + bytes([status, counter])
    body += latency_us.to_bytes(2, "big")
    return with_crc(body, 2)


def hand_frame_94(raw_xyz, status: int, raw_temp_xyz, temp_status: int, counter: int, latency_us: int) -> bytes:
    body = bytes([0x94]) + b"".join(s24(r) for r in raw_xyz) + bytes([status])
    body += b"".join(s16(t) for t in raw_temp_xyz) + bytes([temp_status, counter])
    body += latency_us.to_bytes(2, "big")
    return with_crc(body, 3)


# Table 5-15: 0xB5, 'N', then the 14 digits two to a byte, high nibble first; 7 spare bytes
SERIAL_BODY = bytes([0xB5, 0x4E, 0x25, 0x58, 0x24, 0x05, 0x00, 0x20, 0x02]) + bytes(7)
# Table 5-13, 84167-4400003-321 rev K: byte 1 low nibble digit 1 (8); bytes 2-3 digits 2-5;
# byte 4 '-'; bytes 5-7 digits 6-11 (4 4 0 0 0 0); byte 8 '-'; byte 9 high: digit 13's
# least significant nibble (3), low: digit 14 (2); byte 10 high: digit 15's least (1), low:
# its most significant (0); byte 11 high: digit 13's most significant (0), low: digit 12 (3);
# bytes 12-14 spare; byte 15 the revision 'K'
PART_BODY = bytes([0xB1, 0x08, 0x41, 0x67, 0x2D, 0x44, 0x00, 0x00, 0x2D, 0x32, 0x10, 0x03,
                   0, 0, 0, ord("K")])


def hand_configuration(crlf: bool) -> bytes:
    """Table 5-16 field by field: rev 'B', firmware 7, 250 samples/s, acc + incl, 921600 bit/s,
    accelerometers 30 g on x, y, z."""
    body = bytes([0xBD if crlf else 0xBC, ord("B"), 7,
                  0b001_0_0_1_1_0 | (1 if crlf else 0),     # byte 3: 250 Hz, no PPS/temp, incl, acc
                  0b0010_0_00_0,                             # byte 4: 921600, 1 stop, no parity
                  0x70, 0x00, 0x00, 0x70, 0x00, 0x00, 0x70, 0x00, 0x00, 0x08,   # bytes 5–14
                  0x00, 0x00,                                # bytes 15–16: gyro ranges
                  0x44, 0x40,                                # bytes 17–18: acc 30 g x, y / z
                  0x00, 0x00, 0x00])                         # bytes 19–21
    assert len(body) == 22
    crc = bitwise_crc32_mpeg2(body + bytes(2))               # Table 5-22: 2 dummy bytes
    return body + crc.to_bytes(4, "big") + (b"\r\n" if crlf else b"")
