"""STIM300 datagrams written byte by byte from the datasheet's datagram content tables.

Independent of ``gyrocal.instruments.gyro.datagram``: the tests' oracle for
the wire format. 0x90 (18 bytes): identifier, x/y/z rate (3 × 24-bit two's
complement), status, counter, 2-byte latency, CRC-32. 0x94 (25 bytes):
identifier, x/y/z rate, status, x/y/z temperature (3 × 16-bit two's
complement, 1/256 °C), temperature status, counter, latency, CRC-32. The
CRC covers the datagram padded with dummy 0x00 bytes to a multiple of 4
bytes (2 for 0x90, 3 for 0x94), computed by the bit-by-bit reference.
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
