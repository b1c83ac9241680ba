"""CRC-32/MPEG-2: published check value and an independent bit-by-bit reference."""

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrocal.instruments.gyro.crc32_mpeg2 import (
    CHECK_VALUE,
    crc32_mpeg2,
    crc32_mpeg2_prefix_rows,
    crc32_mpeg2_rows,
    crc32_mpeg2_words,
)

pytestmark = pytest.mark.timeout(60)




def test_published_check_value():
    assert CHECK_VALUE == 0x0376E6E7
    assert crc32_mpeg2(b"123456789") == 0x0376E6E7
    assert bitwise_crc32_mpeg2(b"123456789") == 0x0376E6E7


def test_empty_message_keeps_the_init_value():
    assert crc32_mpeg2(b"") == 0xFFFFFFFF


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=0, max_size=40))
def test_scalar_table_crc_matches_the_bitwise_reference(data):
    assert crc32_mpeg2(data) == bitwise_crc32_mpeg2(data)


@pytest.mark.parametrize("length", [1, 2, 7, 8, 10, 13])
def test_vectorised_rows_match_the_bitwise_reference(length):
    rng = np.random.default_rng(length)
    messages = rng.integers(0, 256, (300, length), dtype=np.uint8)
    got = crc32_mpeg2_rows(messages)
    assert got.dtype == np.uint32
    assert [int(v) for v in got] == [bitwise_crc32_mpeg2(m.tobytes()) for m in messages]


@pytest.mark.parametrize(("n_bytes", "zeros"), [(1, 0), (7, 1), (8, 0), (55, 1), (28, 2), (60, 0)])
def test_prefix_rows_of_a_frame_block_match_the_bitwise_reference(n_bytes, zeros):
    """The compiled per-position form, on a strided block (the first bytes of wider rows)
    followed by dummy zero bytes (the datagram's rule), as the encoder and decoder call it."""
    rng = np.random.default_rng(n_bytes)
    block = rng.integers(0, 256, (257, n_bytes + 5), dtype=np.uint8)
    got = crc32_mpeg2_prefix_rows(block, n_bytes, zeros)
    assert got.dtype == np.uint32
    assert [int(v) for v in got] == [
        bitwise_crc32_mpeg2(row[:n_bytes].tobytes() + bytes(zeros)) for row in block]
    assert crc32_mpeg2_prefix_rows(block[:0], n_bytes, zeros).shape == (0,)


def test_word_form_takes_big_endian_words():
    message = b"12345678"
    words = np.frombuffer(message, dtype=">u2").reshape(1, 4)
    assert int(crc32_mpeg2_words(words)[0]) == bitwise_crc32_mpeg2(message)
    assert int(crc32_mpeg2_words(words.astype(np.uint16))[0]) == bitwise_crc32_mpeg2(message)


def test_appending_the_crc_big_endian_gives_a_zero_remainder():
    """Property of a non-reflected CRC without final XOR: the residue is 0."""
    data = b"\x90\x01\x02\x03\x00\x07\x00\xfa"
    crc = crc32_mpeg2(data)
    assert crc32_mpeg2(data + crc.to_bytes(4, "big")) == 0
