"""Big-endian datagram fields packed and unpacked by compiled loops, as the numpy code does.

Why: the simulated IMU's 0xA7 datagrams carry eight field groups (rates,
accelerometers, inclinometers, three temperature clusters, latency, PPS), and
the numpy encoder (``datagram.py``: ``_to_raw``, ``_overload_bits``, ``_put_int``)
spends ~20 array operations on each group, on blocks of 2,500 frames: ~0.45 ms a
block, 72 % of the encoding, about a second of the simulated gyro's thread in an
IMU dry run, and it holds the interpreter lock the controller needs. One pass
per group over the block does the same rounding (``np.rint``: half to even),
clipping, overload bits and byte order, without the lock. The decoder's field
reads (``datagram._get_int``: a word array filled byte by byte, viewed big-endian,
sign-extended) are the same kind of work on the controller's thread, where every
block of the stream is decoded: one pass per field group there too.

The numpy functions stay as the oracle and the fallback (``tests/instruments/
gyro/test_field_packing.py`` compares the two on random and edge values, both ways).
"""

from __future__ import annotations

from functools import cache

import numpy as np

try:  # numba is a declared dependency; without it datagram.py packs with numpy
    import numba

    @numba.njit(cache=True, nogil=True)
    def _pack_triplet(frames, offset, status_offset, scaled, status, full_scale, width,
                      axis_bits, overload):  # pragma: no cover - compiled
        # the row of the first NaN (nothing written), or -1 once every row is packed
        for i in range(scaled.shape[0]):
            for j in range(scaled.shape[1]):
                if np.isnan(scaled[i, j]):
                    return i
        mask = (1 << (8 * width)) - 1
        for i in range(scaled.shape[0]):
            bits = status[i]
            for j in range(scaled.shape[1]):
                rounded = np.rint(scaled[i, j])
                if rounded > full_scale:
                    rounded = full_scale
                    bits |= overload | axis_bits[j]
                elif rounded < -full_scale:
                    rounded = -full_scale
                    bits |= overload | axis_bits[j]
                value = np.int64(rounded) & mask
                base = offset + j * width
                for b in range(width):
                    frames[i, base + b] = (value >> (8 * (width - 1 - b))) & 0xFF
            frames[i, status_offset] = bits
        return -1

    @numba.njit(cache=True, nogil=True)
    def _pack_ints(frames, offset, values, width):  # pragma: no cover - compiled
        mask = (1 << (8 * width)) - 1
        for i in range(values.shape[0]):
            for j in range(values.shape[1]):
                value = values[i, j] & mask
                base = offset + j * width
                for b in range(width):
                    frames[i, base + b] = (value >> (8 * (width - 1 - b))) & 0xFF

    @numba.njit(cache=True, nogil=True)
    def _unpack_ints(rows, offset, width, signed, out):  # pragma: no cover - compiled
        sign = np.int64(1) << (8 * width - 1)
        for i in range(out.shape[0]):
            for j in range(out.shape[1]):
                base = offset + j * width
                value = np.int64(0)
                for b in range(width):
                    value = (value << 8) | np.int64(rows[i, base + b])
                if signed:
                    value = (value ^ sign) - sign
                out[i, j] = value

    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _pack_triplet = _pack_ints = _unpack_ints = None
    AVAILABLE = False


def pack_triplet(frames: np.ndarray, offset: int, status_offset: int, scaled: np.ndarray,
                 status: np.ndarray, full_scale: int, width: int,
                 axis_bits: tuple[int, ...], overload: int) -> int:
    """Round ``scaled`` (n, 3) to counts (half to even), clip at ± ``full_scale`` setting
    ``overload`` and the clipped axis's bit in ``status`` (n,), and write each value as a
    big-endian two's-complement field of ``width`` bytes from ``offset`` and the status
    byte at ``status_offset``. Returns the row of the first NaN (then nothing is written),
    else -1."""
    assert _pack_triplet is not None, "field_packing.AVAILABLE is False: numba is missing"
    return int(_pack_triplet(frames, offset, status_offset,
                             np.ascontiguousarray(scaled, dtype=np.float64),
                             np.ascontiguousarray(status, dtype=np.uint8), full_scale, width,
                             _axis_bits(axis_bits), np.uint8(overload)))


def pack_ints(frames: np.ndarray, offset: int, values: np.ndarray, width: int) -> None:
    """The columns of integer ``values`` (n, m) as consecutive big-endian ``width``-byte
    fields from ``offset`` (the low ``width`` bytes of each, as two's complement)."""
    assert _pack_ints is not None, "field_packing.AVAILABLE is False: numba is missing"
    _pack_ints(frames, offset, np.ascontiguousarray(values, dtype=np.int64), width)


def unpack_ints(rows: np.ndarray, offset: int, count: int, width: int, signed: bool) -> np.ndarray:
    """``count`` consecutive big-endian ``width``-byte fields from ``offset`` of each row of
    ``rows`` (uint8, 2-D), as int64 (n, count); two's complement when ``signed``."""
    assert _unpack_ints is not None, "field_packing.AVAILABLE is False: numba is missing"
    out = np.empty((rows.shape[0], count), dtype=np.int64)
    _unpack_ints(rows, offset, width, signed, out)
    return out


@cache
def _axis_bits(bits: tuple[int, ...]) -> np.ndarray:
    table = np.array(bits, dtype=np.uint8)
    table.setflags(write=False)
    return table


@cache
def warm_up() -> None:
    """Load the compiled loops now, once per process (their first call costs ~0.1 s of
    CPU, which must not fall inside a wall-time-bounded exchange; see
    ``crc32_mpeg2.warm_up``)."""
    if not AVAILABLE:
        return
    frames = np.zeros((1, 8), dtype=np.uint8)
    pack_triplet(frames, 0, 7, np.zeros((1, 3)), np.zeros(1, np.uint8), 1, 2, (1, 2, 4), 16)
    pack_ints(frames, 0, np.zeros((1, 1), dtype=np.int64), 2)
    received = np.frombuffer(bytes(8), dtype=np.uint8).reshape(1, 8)   # a read block: read-only
    for rows in (frames, received):
        unpack_ints(rows, 0, 1, 2, True)
