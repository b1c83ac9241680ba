"""CRC-32/MPEG-2 as a textbook shift register: the tests' independent reference.

One bit at a time, no tables, no zlib — written from the definition
(poly 0x04C11DB7, init 0xFFFFFFFF, not reflected, no final XOR), so the
vectorised table-driven code under test is checked against something that
shares none of its tricks.
"""


def bitwise_crc32_mpeg2(data: bytes) -> int:
    crc = 0xFFFFFFFF
    for byte in data:
        for bit in range(7, -1, -1):
            feedback = ((crc >> 31) & 1) ^ ((byte >> bit) & 1)
            crc = (crc << 1) & 0xFFFFFFFF
            if feedback:
                crc ^= 0x04C11DB7
    return crc
