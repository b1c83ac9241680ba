"""Modbus RTU framing written from the definition: the tests' reference beside pymodbus.

The product frames RTU through pymodbus; this CRC-16/MODBUS (poly 0xA001 reflected,
init 0xFFFF, sent low byte first) is checked against the Watlow manual's printed
frames and pymodbus's own CRC, so a framing slip on either side shows.
"""

from __future__ import annotations


def crc16_modbus(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` (the value; it goes on the wire low byte first)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def rtu_frame(unit_id: int, pdu: bytes) -> bytes:
    """Address + PDU + CRC (low byte first): the bytes that go on the RS-485 line."""
    body = bytes([unit_id]) + pdu
    return body + crc16_modbus(body).to_bytes(2, "little")


def rtu_frame_ok(frame: bytes) -> bool:
    """True when the last two bytes are the CRC of the rest."""
    return len(frame) >= 4 and crc16_modbus(frame[:-2]).to_bytes(2, "little") == frame[-2:]
