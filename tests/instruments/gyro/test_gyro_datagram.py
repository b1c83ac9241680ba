"""The datagram: golden bytes, round trips, saturation, resync, splits, CRC errors, counter gaps.

The vectorised decoder is checked against a deliberately naive byte-by-byte
scanner written here with ``struct`` and a bit-by-bit CRC, following the
rule stated in the module docstring.
"""

import struct

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrocal.instruments.gyro.datagram import (
    DEFAULT_LSB,
    ID_RATE,
    ID_RATE_TEMP,
    LAYOUT_RATE,
    LAYOUT_RATE_TEMP,
    RAW_FULL_SCALE,
    STATUS_RATE_SATURATED,
    STATUS_TEMP_SATURATED,
    FrameDecoder,
    encode_frames,
)

pytestmark = pytest.mark.timeout(120)

LSB = DEFAULT_LSB




def hand_frame_90(raw_rate: int, status: int, counter: int, latency_us: int) -> bytes:
    body = bytes([0x90]) + (raw_rate & 0xFFFFFF).to_bytes(3, "big") + bytes([status, counter])
    body += latency_us.to_bytes(2, "big")
    return body + bitwise_crc(body).to_bytes(4, "big")


def hand_frame_94(raw_rate: int, status: int, raw_temp: int, counter: int, latency_us: int) -> bytes:
    body = bytes([0x94]) + (raw_rate & 0xFFFFFF).to_bytes(3, "big") + bytes([status])
    body += (raw_temp & 0xFFFF).to_bytes(2, "big") + bytes([counter]) + latency_us.to_bytes(2, "big")
    return body + bitwise_crc(body).to_bytes(4, "big")


def reference_scan(data: bytes, with_temperature: bool):
    """Byte-by-byte scanner: (samples, crc_errors, garbage_bytes); samples are tuples."""
    layout = LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE
    length, ident = layout.length, layout.identifier

    def valid(j):
        if j + length > len(data) or data[j] != ident:
            return False
        return bitwise_crc(data[j : j + length - 4]) == int.from_bytes(data[j + length - 4 : j + length], "big")

    samples, crc_errors, garbage, i = [], 0, 0, 0
    while i + length <= len(data):
        if valid(i):
            frame = data[i : i + length]
            if with_temperature:
                _, r0, r1, r2, status, temp, counter, _lat = struct.unpack(">5BhBH", frame[:10])
            else:
                _, r0, r1, r2, status, counter, _lat = struct.unpack(">6BH", frame[:8])
                temp = None
            raw = int.from_bytes(bytes([r0, r1, r2]), "big", signed=True)
            samples.append((raw, status, counter, temp))
            i += length
        elif data[i] == ident and not any(valid(j) for j in range(i + 1, i + length)):
            crc_errors += 1
            i += length
        else:
            garbage += 1
            i += 1
    return samples, crc_errors, garbage + (len(data) - i)


# --------------------------------------------------------------------------- golden frames


def test_golden_0x90_frame_written_from_the_layout():
    expected = hand_frame_90(raw_rate=16384, status=0, counter=7, latency_us=250)
    assert expected[:8] == bytes.fromhex("90 004000 00 07 00FA")
    got = encode_frames(np.array([1.0]), np.array([7]), latency_us=250)
    assert got == expected
    out = FrameDecoder().feed(expected)
    assert out.rate.tolist() == [1.0] and out.counter.tolist() == [7]
    assert out.latency_us.tolist() == [250] and out.status.tolist() == [0]
    assert out.temp_c is None


def test_golden_0x94_frame_with_negative_rate_and_temperature():
    # -1.5 deg/s = -24576 LSB = 0xFFA000; -12.5 degC = -3200/256 = 0xF380
    expected = hand_frame_94(raw_rate=-24576, status=0, raw_temp=-3200, counter=255, latency_us=1)
    assert expected[:10] == bytes.fromhex("94 FFA000 00 F380 FF 0001")
    got = encode_frames(np.array([-1.5]), np.array([255]), temp_c=np.array([-12.5]), latency_us=1)
    assert got == expected
    out = FrameDecoder(with_temperature=True).feed(expected)
    assert out.rate.tolist() == [-1.5] and out.temp_c.tolist() == [-12.5]
    assert out.counter.tolist() == [255]


def test_custom_lsb_scales_the_raw_value():
    lsb = 1e-3
    frame = encode_frames(np.array([-2.5]), np.array([0]), lsb=lsb)
    assert frame[1:4] == (-2500 & 0xFFFFFF).to_bytes(3, "big")
    assert FrameDecoder(lsb=lsb).feed(frame).rate[0] == pytest.approx(-2.5, abs=1e-12)


# --------------------------------------------------------------------------- round trips


@settings(max_examples=60, deadline=None)
@given(
    raw=st.lists(st.integers(-RAW_FULL_SCALE, RAW_FULL_SCALE), min_size=1, max_size=50),
    first_counter=st.integers(0, 255),
    with_temperature=st.booleans(),
    temp_raw=st.integers(-(2**15) + 1, 2**15 - 1),
)
def test_round_trip_is_exact_on_the_lsb_grid(raw, first_counter, with_temperature, temp_raw):
    raw = np.array(raw, dtype=np.int64)
    rate = raw * LSB
    k = first_counter + np.arange(raw.size)
    temp = np.full(raw.size, temp_raw / 256.0) if with_temperature else None
    data = encode_frames(rate, k, temp_c=temp, latency_us=123)
    layout = LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE
    assert len(data) == raw.size * layout.length
    out = FrameDecoder(with_temperature=with_temperature).feed(data)
    assert np.array_equal(out.rate, rate)
    assert np.array_equal(out.counter, (k % 256).astype(np.uint8))
    assert np.array_equal(out.index, np.arange(raw.size))
    assert not out.status.any() and out.lost_frames == 0
    assert out.crc_errors == 0 and out.garbage_bytes == 0
    if with_temperature:
        assert np.array_equal(out.temp_c, temp)
    # The naive decoder agrees field by field.
    samples, _, _ = reference_scan(data, with_temperature)
    assert [s[0] for s in samples] == raw.tolist()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-500.0, 500.0, allow_nan=False), min_size=1, max_size=30))
def test_round_trip_of_arbitrary_rates_is_within_half_an_lsb(rates):
    rate = np.array(rates)
    out = FrameDecoder().feed(encode_frames(rate, np.arange(rate.size)))
    assert np.all(np.abs(out.rate - rate) <= LSB / 2 + 1e-12)


# --------------------------------------------------------------------------- saturation


def test_saturation_is_clipped_and_flagged_never_wrapped():
    full_scale = RAW_FULL_SCALE * LSB
    rate = np.array([full_scale, full_scale + LSB, -full_scale - 1000, np.inf, -np.inf, 0.0])
    out = FrameDecoder().feed(encode_frames(rate, np.arange(rate.size)))
    assert out.rate.tolist() == [full_scale, full_scale, -full_scale, full_scale, -full_scale, 0.0]
    flagged = (out.status & STATUS_RATE_SATURATED) != 0
    assert flagged.tolist() == [False, True, True, True, True, False]


def test_temperature_saturation_is_flagged():
    out = FrameDecoder(with_temperature=True).feed(
        encode_frames(np.zeros(2), np.arange(2), temp_c=np.array([25.0, 400.0]))
    )
    assert out.temp_c.tolist() == [25.0, (2**15 - 1) / 256]
    assert ((out.status & STATUS_TEMP_SATURATED) != 0).tolist() == [False, True]


def test_nan_rate_is_refused_with_its_position():
    with pytest.raises(ValueError, match=r"rate\[2\] is NaN"):
        encode_frames(np.array([0.0, 1.0, np.nan]), np.arange(3))


# --------------------------------------------------------------------------- resync and errors


def test_stray_identifier_byte_before_a_frame_does_not_cost_the_frame():
    frames = encode_frames(np.arange(4.0), np.arange(4))
    data = frames[:12] + bytes([ID_RATE]) + frames[12:24] + bytes([ID_RATE, ID_RATE]) + frames[24:]
    out = FrameDecoder().feed(data)
    assert out.rate.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert out.garbage_bytes == 3 and out.crc_errors == 0 and out.lost_frames == 0


def test_frames_of_the_other_type_are_skipped_as_garbage():
    data = (
        encode_frames(np.array([1.0]), [0])
        + encode_frames(np.array([9.0]), [1], temp_c=np.array([20.0]))
        + encode_frames(np.array([2.0]), [1])
    )
    out = FrameDecoder().feed(data)
    assert out.rate.tolist() == [1.0, 2.0] and out.garbage_bytes == LAYOUT_RATE_TEMP.length


def test_corrupt_frame_is_dropped_counted_and_leaves_a_counter_gap():
    frames = bytearray(encode_frames(np.arange(10.0), np.arange(10)))
    frames[4 * 12 + 2] ^= 0x01                      # one bit in frame 4's rate
    out = FrameDecoder().feed(bytes(frames))
    assert out.rate.tolist() == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert out.index.tolist() == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert out.crc_errors == 1 and out.lost_frames == 1 and out.garbage_bytes == 0


def test_corrupt_crc_field_is_caught_too():
    frames = bytearray(encode_frames(np.arange(3.0), np.arange(3)))
    frames[12 + 11] ^= 0x80                         # last CRC byte of frame 1
    out = FrameDecoder().feed(bytes(frames))
    assert out.rate.tolist() == [0.0, 2.0] and out.crc_errors == 1


def test_counter_gap_across_the_wrap_is_unwrapped():
    k = np.r_[np.arange(250, 256), np.arange(259, 263)]       # 256, 257, 258 never sent
    decoder = FrameDecoder()
    out = decoder.feed(encode_frames(np.zeros(k.size), k))
    assert out.counter.tolist() == [250, 251, 252, 253, 254, 255, 3, 4, 5, 6]
    assert out.index.tolist() == [0, 1, 2, 3, 4, 5, 9, 10, 11, 12]
    assert out.lost_frames == 3
    # The gap bookkeeping continues across feeds.
    out2 = decoder.feed(encode_frames(np.zeros(2), np.array([270, 271])))
    assert out2.index.tolist() == [20, 21] and out2.lost_frames == 7
    assert decoder.total_lost_frames == 10


def test_reset_forgets_partial_frames_and_restarts_the_index():
    decoder = FrameDecoder()
    data = encode_frames(np.arange(3.0), np.arange(100, 103))
    decoder.feed(data[:20])
    assert decoder.pending_bytes == 8
    decoder.reset()
    assert decoder.pending_bytes == 0
    out = decoder.feed(data[24:])
    assert out.index.tolist() == [0] and out.rate.tolist() == [2.0] and out.garbage_bytes == 0


def build_disturbed_stream(seed: int, with_temperature: bool, garbage_probability: float = 0.3):
    """Frames with garbage runs (rich in identifier bytes) and corrupted frames.

    Returns (stream, good sample raw values in order); the stream ends with
    two clean frames so that everything before them is decidable.
    """
    rng = np.random.default_rng(seed)
    layout = LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE
    n = int(rng.integers(5, 60))
    raw = rng.integers(-RAW_FULL_SCALE, RAW_FULL_SCALE, n)
    temp = rng.integers(-3000, 3000, n) / 256.0 if with_temperature else None
    frames = bytearray(encode_frames(raw * LSB, np.arange(n), temp_c=temp))
    good = []
    pieces = []
    for j in range(n):
        frame = bytearray(frames[j * layout.length : (j + 1) * layout.length])
        if j < n - 2 and rng.random() < 0.15:
            frame[int(rng.integers(1, layout.length))] ^= int(rng.integers(1, 256))
        else:
            good.append(int(raw[j]))
        if j < n - 2 and rng.random() < garbage_probability:
            garbage = rng.integers(0, 256, int(rng.integers(1, 3 * layout.length)), dtype=np.uint8)
            ids = rng.random(garbage.size) < 0.3
            garbage[ids] = rng.choice([ID_RATE, ID_RATE_TEMP], int(ids.sum()))
            pieces.append(garbage.tobytes())
        pieces.append(bytes(frame))
    return b"".join(pieces), good


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), with_temperature=st.booleans())
def test_vectorised_decoder_agrees_with_the_byte_by_byte_scanner(seed, with_temperature):
    stream, good = build_disturbed_stream(seed, with_temperature)
    samples, crc_errors, garbage = reference_scan(stream, with_temperature)
    decoder = FrameDecoder(with_temperature=with_temperature)
    out = decoder.feed(stream)
    raw = np.rint(out.rate / LSB).astype(np.int64).tolist()
    assert raw == [s[0] for s in samples] == good      # every good frame, nothing corrupt
    assert out.crc_errors == crc_errors
    assert out.garbage_bytes == garbage
    assert decoder.pending_bytes == 0
    layout = decoder.layout
    assert layout.length * (len(out) + out.crc_errors) + out.garbage_bytes == len(stream)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), with_temperature=st.booleans())
def test_aligned_stream_with_corrupt_frames_agrees_with_the_scanner(seed, with_temperature):
    """Corruption without garbage keeps frames aligned (the decoder's fast path)."""
    stream, good = build_disturbed_stream(seed, with_temperature, garbage_probability=0.0)
    samples, crc_errors, garbage = reference_scan(stream, with_temperature)
    out = FrameDecoder(with_temperature=with_temperature).feed(stream)
    assert np.rint(out.rate / LSB).astype(np.int64).tolist() == [s[0] for s in samples]
    assert (out.crc_errors, out.garbage_bytes) == (crc_errors, garbage)


def test_valid_frame_hidden_across_aligned_rows_still_wins():
    """Two rows that start with the identifier but hold garbage around a frame.

    Every row boundary carries 0x90, so only the check for CRC-valid frames
    inside failed rows can find the embedded frame.
    """
    hidden = encode_frames(np.array([5.0]), [3], latency_us=0x9000)
    assert hidden[6] == ID_RATE
    frames = encode_frames(np.arange(3.0), np.arange(3))
    tail = encode_frames(np.array([6.0, 7.0]), [4, 5])
    stream = frames + bytes([ID_RATE, 1, 2, 3, 4, 5]) + hidden + bytes(6) + tail
    out = FrameDecoder().feed(stream)
    assert out.rate.tolist() == [0.0, 1.0, 2.0, 5.0, 6.0, 7.0]
    assert out.garbage_bytes == 12 and out.crc_errors == 0
    assert reference_scan(stream, False)[1:] == (0, 12)


@pytest.mark.parametrize("with_temperature", [False, True])
def test_split_at_every_offset_gives_the_same_result(with_temperature):
    stream, good = build_disturbed_stream(12345, with_temperature)
    whole = FrameDecoder(with_temperature=with_temperature).feed(stream)
    for cut in range(len(stream) + 1):
        decoder = FrameDecoder(with_temperature=with_temperature)
        first, second = decoder.feed(stream[:cut]), decoder.feed(stream[cut:])
        rate = np.concatenate([first.rate, second.rate])
        index = np.concatenate([first.index, second.index])
        assert np.array_equal(rate, whole.rate), cut
        assert np.array_equal(index, whole.index), cut
        assert first.crc_errors + second.crc_errors == whole.crc_errors, cut
        assert first.garbage_bytes + second.garbage_bytes == whole.garbage_bytes, cut
        assert decoder.pending_bytes == 0


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_small_chunks_give_the_same_result(seed):
    stream, good = build_disturbed_stream(seed, False)
    rng = np.random.default_rng(seed)
    decoder = FrameDecoder()
    parts, crc_errors, garbage, position = [], 0, 0, 0
    while position < len(stream):
        size = int(rng.integers(1, 30))
        out = decoder.feed(stream[position : position + size])
        parts.append(out.rate)
        crc_errors += out.crc_errors
        garbage += out.garbage_bytes
        position += size
    samples, ref_crc, ref_garbage = reference_scan(stream, False)
    assert np.rint(np.concatenate(parts) / LSB).astype(np.int64).tolist() == good
    assert (crc_errors, garbage) == (ref_crc, ref_garbage)


def test_large_clean_buffer_with_sparse_corruption_counts_exactly():
    n = 200_000
    rng = np.random.default_rng(7)
    raw = rng.integers(-RAW_FULL_SCALE, RAW_FULL_SCALE, n)
    frames = np.frombuffer(encode_frames(raw * LSB, np.arange(n)), dtype=np.uint8).reshape(n, 12).copy()
    corrupt = np.sort(rng.choice(n - 2, 2000, replace=False))
    frames[corrupt, 3] ^= 0x5A
    out = FrameDecoder().feed(frames.tobytes())
    keep = np.ones(n, dtype=bool)
    keep[corrupt] = False
    assert np.array_equal(np.rint(out.rate / LSB).astype(np.int64), raw[keep])
    assert out.crc_errors == 2000 and out.garbage_bytes == 0
    assert out.lost_frames == 2000
    assert np.array_equal(out.index, np.flatnonzero(keep))
