"""CRC-32/MPEG-2 for the gyro datagram, scalar and vectorised over many frames.

Parameters: polynomial 0x04C11DB7, init 0xFFFFFFFF, not reflected, no final
XOR (the CRC the STIM300 family appends to its datagrams; published check
value for ``b"123456789"`` is 0x0376E6E7). ``zlib.crc32`` is the *reflected*
CRC-32 with a final XOR, so it cannot be used.

Why the vectorised form looks the way it does: a decoder at 2 kHz × hours,
or a benchmark at millions of frames, must check the CRC of every candidate
frame in one go. Processing bytes one column at a time needs a shift, a
lookup and two XORs per byte with a dependency chain through the register.
Instead we use linearity over GF(2): for a message of fixed length ``m``,

    crc(msg) = crc_of_zeros(m) XOR  ⊕_j  W_k(j)[word_j]

where ``word_j`` is the j-th big-endian 16-bit word of the message and
``W_k`` is a 65 536-entry table holding the CRC (zero init) of that word
followed by ``k`` zero bytes. Every lookup is independent, so a frame of
8 (or 10) message bytes costs 4 (or 5) table lookups and XORs per frame, all
done column-wise in numpy over the whole candidate array ("slicing by 16-bit
words with position-specific tables").
"""

from __future__ import annotations

from functools import cache

import numpy as np

POLY = 0x04C11DB7
INIT = 0xFFFFFFFF
CHECK_VALUE = 0x0376E6E7   # crc32_mpeg2(b"123456789"), published check value


def _byte_table() -> np.ndarray:
    """Classic MSB-first table: CRC (zero init) of each single byte value."""
    crc = np.arange(256, dtype=np.uint32) << np.uint32(24)
    for _ in range(8):
        top = (crc & np.uint32(0x80000000)) != 0
        crc = np.where(top, (crc << np.uint32(1)) ^ np.uint32(POLY), crc << np.uint32(1))
    return crc.astype(np.uint32)


BYTE_TABLE = _byte_table()
_BYTE_TABLE_LIST = [int(v) for v in BYTE_TABLE]


def crc32_mpeg2(data: bytes | bytearray | memoryview, crc: int = INIT) -> int:
    """Scalar table-driven CRC-32/MPEG-2 (for single messages and tests)."""
    table = _BYTE_TABLE_LIST
    for byte in bytes(data):
        crc = ((crc << 8) & 0xFFFFFFFF) ^ table[(crc >> 24) ^ byte]
    return crc


def _append_zero_byte(crc: np.ndarray) -> np.ndarray:
    """Advance CRC registers over one zero byte (vectorised)."""
    return (crc << np.uint32(8)) ^ BYTE_TABLE[crc >> np.uint32(24)]


@cache
def _zero_followed_byte_tables(max_zeros: int) -> tuple[np.ndarray, ...]:
    """Z[k][b] = CRC (zero init) of byte ``b`` followed by ``k`` zero bytes."""
    tables = [BYTE_TABLE.copy()]
    for _ in range(max_zeros):
        tables.append(_append_zero_byte(tables[-1]))
    return tuple(tables)


@cache
def word_table(trailing_zero_bytes: int) -> np.ndarray:
    """W_k[w]: CRC (zero init) of big-endian 16-bit word ``w`` followed by ``k`` zero bytes."""
    z = _zero_followed_byte_tables(trailing_zero_bytes + 1)
    words = np.arange(65536, dtype=np.uint32)
    table = z[trailing_zero_bytes + 1][words >> np.uint32(8)] ^ z[trailing_zero_bytes][words & np.uint32(0xFF)]
    table.setflags(write=False)
    return table


@cache
def init_term(message_bytes: int) -> int:
    """Contribution of the 0xFFFFFFFF init to the CRC of any ``message_bytes``-long message."""
    return crc32_mpeg2(bytes(message_bytes))


def crc32_mpeg2_words(words: np.ndarray) -> np.ndarray:
    """CRC of many equal-length messages given as big-endian 16-bit words.

    ``words`` is a 2-D array (n_messages, n_words) of uint16 (any byte order
    dtype holding the big-endian word values, e.g. a ``>u2`` view of the
    message bytes). Returns uint32 CRCs, one per row.
    """
    n_words = words.shape[1]
    crc = np.full(words.shape[0], init_term(2 * n_words), dtype=np.uint32)
    for j in range(n_words):
        table = word_table(2 * (n_words - 1 - j))
        crc ^= table[words[:, j]]
    return crc


def crc32_mpeg2_rows(messages: np.ndarray) -> np.ndarray:
    """CRC of each row of a 2-D uint8 array (rows of even length use the word path)."""
    messages = np.ascontiguousarray(messages, dtype=np.uint8)
    n_rows, n_bytes = messages.shape
    if n_bytes % 2:
        # Odd length has no whole-word split: byte-column form (one lookup per byte).
        crc = np.full(n_rows, INIT, dtype=np.uint32)
        for j in range(n_bytes):
            crc = (crc << np.uint32(8)) ^ BYTE_TABLE[(crc >> np.uint32(24)) ^ messages[:, j]]
        return crc
    return crc32_mpeg2_words(messages.view(">u2"))


# Compiled, for the datagrams of a stream: a block of 0xA7 frames (55 message bytes and a
# dummy zero byte each) took ~180 µs per 2,300 frames through the word tables (28 gathers
# from 256 KiB tables, and a padded copy of the block first): ~0.6 s of an IMU dry run's
# encoding and as much of its decoding. The same linearity with one 256-entry table per
# byte position (57 KiB in all, in cache) and no copy: ~4x less.
try:  # numba is a declared dependency; without it the word tables above do the work
    import numba

    @numba.njit(cache=True, nogil=True)
    def _position_crc(rows, n_bytes, tables, init, out):  # pragma: no cover - compiled
        for i in range(rows.shape[0]):
            crc = init
            for j in range(n_bytes):
                crc ^= tables[j, rows[i, j]]
            out[i] = crc
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _position_crc = None


@cache
def position_tables(message_bytes: int) -> np.ndarray:
    """T[j][b]: CRC (zero init) of byte ``b`` at position ``j`` of a ``message_bytes`` message
    (followed by ``message_bytes - 1 - j`` zero bytes)."""
    z = _zero_followed_byte_tables(message_bytes - 1)
    tables = np.stack([z[message_bytes - 1 - j] for j in range(message_bytes)]).astype(np.uint32)
    tables.setflags(write=False)
    return tables


def crc32_mpeg2_prefix_rows(rows: np.ndarray, n_bytes: int, trailing_zero_bytes: int = 0) -> np.ndarray:
    """CRC of each row's first ``n_bytes`` bytes followed by ``trailing_zero_bytes`` zero bytes.

    ``rows``: a 2-D uint8 array (any row stride: a block of frames as it is); uint32 per row.
    """
    message_bytes = n_bytes + trailing_zero_bytes
    if _position_crc is None or rows.dtype != np.uint8 or rows.ndim != 2:
        padded = np.zeros((rows.shape[0], message_bytes), dtype=np.uint8)
        padded[:, :n_bytes] = rows[:, :n_bytes]
        return crc32_mpeg2_rows(padded)
    out = np.empty(rows.shape[0], dtype=np.uint32)
    _position_crc(rows, n_bytes, position_tables(message_bytes), np.uint32(init_term(message_bytes)), out)
    return out


@cache
def warm_up() -> None:
    """Load the compiled CRC now, once per process, for blocks as the encoder makes them
    and as the decoder reads them (read-only views of the received bytes): its first call
    costs ~0.1 s of CPU, more wall time on a loaded machine, which must not fall inside a
    wall-time-bounded exchange (see ``models/recursion.warm_up``)."""
    block = np.zeros((1, 4), dtype=np.uint8)
    received = np.frombuffer(bytes(4), dtype=np.uint8).reshape(1, 4)
    for rows in (block, received, block[:, :3], received[:, :3]):
        crc32_mpeg2_prefix_rows(rows, 2, 1)
