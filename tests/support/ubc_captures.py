"""Real STIM300 captures kept as test fixtures (tests/instruments/gyro/captures/README.md).

``struct_reader`` reads 0x93 with CR LF field by field from TS1524 Table 5-20
(p. 36) with ``struct``/``int.from_bytes``, independent of the decoder.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

CAPTURES = Path(__file__).resolve().parents[1] / "instruments" / "gyro" / "captures"
FAST = CAPTURES / "imu_uart_data_2_datagrams400-799.txt"     # 2000 Hz, 400 datagrams
SLOW = CAPTURES / "imu_uart_data_3_first300.txt"             # 125 Hz, 300 datagrams
FRAME = 40        # 0x93: 38 bytes (Table 5-20 without temperatures and PPS) + CR LF


def struct_reader(data: bytes, range_lsb_g: float) -> dict[str, np.ndarray]:
    """0x93 field by field (Table 5-20): id, 3×24-bit rate, status, 3×24 acc, status,
    3×24 incl, status, counter, 16-bit latency, CRC, CR LF."""
    def s24(b: bytes) -> int:
        return int.from_bytes(b, "big", signed=True)

    rows = [data[i:i + FRAME] for i in range(0, len(data) - FRAME + 1, FRAME)]
    assert all(r[0] == 0x93 and r[38:40] == b"\r\n" for r in rows)
    return {
        "rate": np.array([[s24(r[1 + 3 * a:4 + 3 * a]) for a in range(3)] for r in rows]) / 2**14,
        "acc": np.array([[s24(r[11 + 3 * a:14 + 3 * a]) for a in range(3)] for r in rows]) * range_lsb_g,
        "incl": np.array([[s24(r[21 + 3 * a:24 + 3 * a]) for a in range(3)] for r in rows]) / 2**22,
        "status": np.array([[r[10], r[20], r[30]] for r in rows]),
        "counter": np.array([r[31] for r in rows]),
        "latency": np.array([struct.unpack(">H", r[32:34])[0] for r in rows]),
    }
