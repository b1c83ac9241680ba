"""The datagram: golden bytes, round trips, saturation, resync, splits, CRC errors, counter gaps.

Expected bytes come from the STIM300 datasheet's datagram content tables,
written field by field by the helpers below (no import of the encoder's
layout): 0x90 = identifier, 3 × 24-bit rates, status, counter, 2-byte
latency, CRC (18 bytes); 0x94 = identifier, 3 rates, status, 3 × 16-bit
temperatures, temperature status, counter, latency, CRC (25 bytes). The
CRC is computed over the datagram padded with dummy 0x00 bytes to a multiple
of 4 (2 for 0x90, 3 for 0x94) by a bit-by-bit reference CRC-32/MPEG-2.
The vectorised decoder is checked against a deliberately naive byte-by-byte
scanner written here with ``struct``, following the rule stated in the
module docstring.
"""

import struct

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc
from hypothesis import given, settings
from hypothesis import strategies as st
from stim300_bytes import hand_frame_90, hand_frame_94

from gyrocal.instruments.gyro.datagram import (
    DEFAULT_LSB,
    ID_RATE,
    ID_RATE_TEMP,
    LAYOUT_RATE,
    LAYOUT_RATE_TEMP,
    RAW_FULL_SCALE,
    FrameDecoder,
    encode_frames,
    flagged,
)

pytestmark = pytest.mark.timeout(120)

LSB = DEFAULT_LSB
LEN_90, LEN_94 = 18, 25          # datasheet datagram lengths (without CR LF)
OVERLOAD, AXIS_X, AXIS_Y, AXIS_Z = 0x10, 0x01, 0x02, 0x04   # datasheet status bits 4, 0, 1, 2


def xyz(x, y=None, z=None) -> np.ndarray:
    """(n, 3) rates: ``x`` on the x axis; y/z default to -x and x reversed (same LSB grid, other values)."""
    x = np.asarray(x, dtype=np.float64)
    y = -x if y is None else np.asarray(y, dtype=np.float64)
    z = x[::-1] if z is None else np.asarray(z, dtype=np.float64)
    return np.stack([x, np.broadcast_to(y, x.shape), np.broadcast_to(z, x.shape)], axis=1)


def reference_scan(data: bytes, with_temperature: bool):
    """Byte-by-byte scanner: (samples, crc_errors, garbage_bytes); samples are (raw_x, status, counter, temp_x)."""
    length = LEN_94 if with_temperature else LEN_90
    ident = 0x94 if with_temperature else 0x90
    dummy = 3 if with_temperature else 2

    def valid(j):
        if j + length > len(data) or data[j] != ident:
            return False
        return bitwise_crc(data[j : j + length - 4] + bytes(dummy)) == int.from_bytes(
            data[j + length - 4 : j + length], "big")

    samples, crc_errors, garbage, i = [], 0, 0, 0
    while i + length <= len(data):
        if valid(i):
            frame = data[i : i + length]
            raw = int.from_bytes(frame[1:4], "big", signed=True)
            if with_temperature:
                status, tx, _ty, _tz, _tstat, counter, _lat = struct.unpack(">BhhhBBH", frame[10:21])
                temp = tx
            else:
                status, counter, _lat = struct.unpack(">BBH", frame[10:14])
                temp = None
            samples.append((raw, status, counter, temp))
            i += length
        elif data[i] == ident and not any(valid(j) for j in range(i + 1, i + length)):
            crc_errors += 1
            i += length
        else:
            garbage += 1
            i += 1
    return samples, crc_errors, garbage + (len(data) - i)


def test_reference_crc_is_the_published_crc32_mpeg2():
    # The reference is a shift register written from the definition; its check value
    # is the published CRC-32/MPEG-2 "123456789" -> 0x0376E6E7 (CRC RevEng catalogue).
    assert bitwise_crc(b"123456789") == 0x0376E6E7


# --------------------------------------------------------------------------- golden frames


def test_golden_0x90_frame_written_from_the_datasheet_table():
    expected = hand_frame_90((16384, -8192, 4096), status=0, counter=7, latency_us=250)
    assert len(expected) == LEN_90 == LAYOUT_RATE.length
    assert expected[:14] == bytes.fromhex("90 004000 FFE000 001000 00 07 00FA")
    got = encode_frames(xyz([1.0], [-0.5], [0.25]), np.array([7]), latency_us=250)
    assert got == expected
    out = FrameDecoder().feed(expected)
    assert out.rate.tolist() == [[1.0, -0.5, 0.25]] and out.counter.tolist() == [7]
    assert out.latency_us.tolist() == [250] and out.status.tolist() == [0]
    assert out.temp_c is None


def test_datasheet_built_0x94_frame_decodes_to_three_rates_and_temperatures():
    # x 1.0 deg/s = 16384 LSB = 0x004000; y -1.5 deg/s = -24576 = 0xFFA000;
    # z 400 deg/s = 6553600 = 0x640000. Temperatures 25.0 / -12.5 / 30.5 degC
    # = 6400 / -3200 / 7808 in 1/256 degC = 0x1900 / 0xF380 / 0x1E80.
    expected = hand_frame_94((16384, -24576, 6553600), status=0, raw_temp_xyz=(6400, -3200, 7808),
                             temp_status=0, counter=255, latency_us=500)
    assert len(expected) == LEN_94 == LAYOUT_RATE_TEMP.length
    assert expected[:21] == bytes.fromhex("94 004000 FFA000 640000 00 1900 F380 1E80 00 FF 01F4")
    out = FrameDecoder(with_temperature=True).feed(expected)
    assert out.rate.tolist() == [[1.0, -1.5, 400.0]]
    assert out.temp_c.tolist() == [[25.0, -12.5, 30.5]]
    assert out.counter.tolist() == [255] and out.latency_us.tolist() == [500]
    assert out.status.tolist() == [0] and out.temp_status.tolist() == [0]
    got = encode_frames(xyz([1.0], [-1.5], [400.0]), np.array([255]),
                        temp_c=np.array([[25.0, -12.5, 30.5]]), latency_us=500)
    assert got == expected


def test_crc_without_the_dummy_bytes_is_rejected():
    """A frame whose CRC covers only the 14 real bytes (no padding) is not a datagram."""
    body = bytes.fromhex("90 004000 FFE000 001000 00 07 00FA")
    wrong = body + bitwise_crc(body).to_bytes(4, "big")
    out = FrameDecoder().feed(wrong + hand_frame_90((1, 2, 3), 0, 8, 0) + hand_frame_90((1, 2, 3), 0, 9, 0))
    assert len(out) == 2 and out.crc_errors == 1


@pytest.mark.parametrize("with_temperature", [False, True])
def test_cr_lf_terminated_datagrams(with_temperature):
    if with_temperature:
        frames = [hand_frame_94((i, -i, 2 * i), 0, (100, 200, 300), 0, i, 0) for i in range(4)]
    else:
        frames = [hand_frame_90((i, -i, 2 * i), 0, i, 0) for i in range(4)]
    stream = b"\r\n".join(frames) + b"\r\n"
    decoder = FrameDecoder(with_temperature=with_temperature, crlf=True)
    out = decoder.feed(b"\x0d\x0a\x90" + stream)         # a partial line before the first datagram
    assert (out.rate / LSB).tolist() == [[i, -i, 2 * i] for i in range(4)]
    assert out.garbage_bytes == 3 and out.crc_errors == 0 and decoder.pending_bytes == 0
    # Without the CR LF setting the terminators are skipped as garbage, nothing is lost.
    plain_decoder = FrameDecoder(with_temperature=with_temperature)
    plain = plain_decoder.feed(stream)
    # three terminators skipped; the last one waits for more bytes (it could start a frame)
    assert len(plain) == 4 and plain.garbage_bytes == 6 and plain_decoder.pending_bytes == 2
    # The encoder's CR LF form is the hand-built one.
    temp = np.array([[100, 200, 300]]) / 256 if with_temperature else None
    assert encode_frames(xyz([0.0]), [0], temp_c=temp, crlf=True) == frames[0] + b"\r\n"
    # A terminator that is not CR LF makes the datagram invalid under crlf=True.
    broken = bytearray(stream)
    broken[len(frames[0]) + 1] = 0x00
    assert len(FrameDecoder(with_temperature=with_temperature, crlf=True).feed(bytes(broken))) == 3


def test_custom_lsb_scales_the_raw_value():
    lsb = 1e-3
    frame = encode_frames(xyz([-2.5]), np.array([0]), lsb=lsb)
    assert frame[1:4] == (-2500 & 0xFFFFFF).to_bytes(3, "big")
    assert FrameDecoder(lsb=lsb).feed(frame).rate[0, 0] == pytest.approx(-2.5, abs=1e-12)


def test_fields_written_big_endian_whatever_the_memory_order_of_the_input():
    """A simulator may hand a transposed (Fortran-order) block: the bytes are the rows'
    values big-endian (TS1524 Table 5-4: rate fields 24-bit two's complement, MSB first)."""
    values = [[-3e-3, 1.0, 4e-4], [7.0, -1.0, 0.0]]
    fortran = np.asfortranarray(np.array(values))
    frames = encode_frames(fortran, np.array([0, 1]), temp_c=np.full((3, 2), 21.0).T, lsb=1e-3)
    assert frames == encode_frames(np.array(values), np.array([0, 1]), temp_c=np.full((2, 3), 21.0),
                                   lsb=1e-3)
    first = frames[:LEN_94]
    assert first[1:10] == b"".join((r & 0xFFFFFF).to_bytes(3, "big") for r in (-3, 1000, 0))


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
    temp = np.tile([temp_raw / 256.0, -temp_raw / 256.0, 0.5], (raw.size, 1)) if with_temperature else None
    data = encode_frames(xyz(rate), k, temp_c=temp, latency_us=123)
    layout = LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE
    assert len(data) == raw.size * layout.length
    out = FrameDecoder(with_temperature=with_temperature).feed(data)
    assert np.array_equal(out.rate, xyz(rate))
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
    out = FrameDecoder().feed(encode_frames(xyz(rate), np.arange(rate.size)))
    assert np.all(np.abs(out.rate - xyz(rate)) <= LSB / 2 + 1e-12)


# --------------------------------------------------------------------------- saturation


def test_saturation_is_clipped_and_flagged_never_wrapped():
    full_scale = RAW_FULL_SCALE * LSB
    rate = np.array([full_scale, full_scale + LSB, -full_scale - 1000, np.inf, -np.inf, 0.0])
    out = FrameDecoder().feed(encode_frames(xyz(rate, 0.0, 0.0), np.arange(rate.size)))
    assert out.rate[:, 0].tolist() == [full_scale, full_scale, -full_scale, full_scale, -full_scale, 0.0]
    # Datasheet status byte: bit 4 overload, bit 0 the x channel.
    assert out.status.tolist() == [0, OVERLOAD | AXIS_X, OVERLOAD | AXIS_X, OVERLOAD | AXIS_X,
                                   OVERLOAD | AXIS_X, 0]


def test_saturation_names_each_axis():
    big = 2 * RAW_FULL_SCALE * LSB
    out = FrameDecoder().feed(encode_frames(xyz([0.0, 0.0], [big, 0.0], [big, -big]), np.arange(2)))
    assert out.status.tolist() == [OVERLOAD | AXIS_Y | AXIS_Z, OVERLOAD | AXIS_Z]
    assert flagged(out.status, 0).tolist() == [False, False]
    assert flagged(out.status, 1).tolist() == [True, False]
    assert flagged(out.status, 2).tolist() == [True, True]


def test_status_bits_per_axis_from_the_datasheet_table():
    status = np.array([0x00, 0x80, 0x40, 0x20, 0x10, 0x11, 0x0A, 0x08, 0x01], dtype=np.uint8)
    # bit 7 system integrity, 6 start-up, 5 outside operating conditions: every axis;
    # bit 4 overload / bit 3 channel error: the axes whose bit 0..2 is set (all if none).
    assert flagged(status, 0).tolist() == [False, True, True, True, True, True, False, True, False]
    assert flagged(status, 1).tolist() == [False, True, True, True, True, False, True, True, False]
    assert flagged(status, 2).tolist() == [False, True, True, True, True, False, False, True, False]


def test_temperature_saturation_is_flagged():
    out = FrameDecoder(with_temperature=True).feed(
        encode_frames(xyz(np.zeros(2)), np.arange(2), temp_c=np.array([[25.0, 25.0, 25.0], [25.0, 400.0, 25.0]]))
    )
    assert out.temp_c[:, 1].tolist() == [25.0, (2**15 - 1) / 256]
    assert out.temp_status.tolist() == [0, OVERLOAD | AXIS_Y]
    assert out.status.tolist() == [0, 0]


def test_nan_rate_is_refused_with_its_position():
    with pytest.raises(ValueError, match=r"rate\[2\] is NaN"):
        encode_frames(xyz([0.0, 1.0, np.nan], 0.0, 0.0), np.arange(3))


# --------------------------------------------------------------------------- resync and errors


def test_stray_identifier_byte_before_a_frame_does_not_cost_the_frame():
    frames = encode_frames(xyz(np.arange(4.0)), np.arange(4))
    L = LEN_90
    data = frames[:L] + bytes([ID_RATE]) + frames[L:2 * L] + bytes([ID_RATE, ID_RATE]) + frames[2 * L:]
    out = FrameDecoder().feed(data)
    assert out.rate[:, 0].tolist() == [0.0, 1.0, 2.0, 3.0]
    assert out.garbage_bytes == 3 and out.crc_errors == 0 and out.lost_frames == 0


def test_frames_of_the_other_type_are_skipped_as_garbage():
    data = (
        encode_frames(xyz([1.0]), [0])
        + encode_frames(xyz([9.0]), [1], temp_c=np.array([[20.0, 20.0, 20.0]]))
        + encode_frames(xyz([2.0]), [1])
    )
    out = FrameDecoder().feed(data)
    assert out.rate[:, 0].tolist() == [1.0, 2.0] and out.garbage_bytes == LEN_94


def test_corrupt_frame_is_dropped_counted_and_leaves_a_counter_gap():
    frames = bytearray(encode_frames(xyz(np.arange(10.0)), np.arange(10)))
    frames[4 * LEN_90 + 2] ^= 0x01                  # one bit in frame 4's x rate
    out = FrameDecoder().feed(bytes(frames))
    assert out.rate[:, 0].tolist() == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert out.index.tolist() == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    assert out.crc_errors == 1 and out.lost_frames == 1 and out.garbage_bytes == 0


def test_corrupt_crc_field_is_caught_too():
    frames = bytearray(encode_frames(xyz(np.arange(3.0)), np.arange(3)))
    frames[LEN_90 + 17] ^= 0x80                     # last CRC byte of frame 1
    out = FrameDecoder().feed(bytes(frames))
    assert out.rate[:, 0].tolist() == [0.0, 2.0] and out.crc_errors == 1


def test_counter_gap_across_the_wrap_is_unwrapped():
    k = np.r_[np.arange(250, 256), np.arange(259, 263)]       # 256, 257, 258 never sent
    decoder = FrameDecoder()
    out = decoder.feed(encode_frames(xyz(np.zeros(k.size)), k))
    assert out.counter.tolist() == [250, 251, 252, 253, 254, 255, 3, 4, 5, 6]
    assert out.index.tolist() == [0, 1, 2, 3, 4, 5, 9, 10, 11, 12]
    assert out.lost_frames == 3
    # The gap bookkeeping continues across feeds.
    out2 = decoder.feed(encode_frames(xyz(np.zeros(2)), np.array([270, 271])))
    assert out2.index.tolist() == [20, 21] and out2.lost_frames == 7
    assert decoder.total_lost_frames == 10


def test_reset_forgets_partial_frames_and_restarts_the_index():
    decoder = FrameDecoder()
    data = encode_frames(xyz(np.arange(3.0)), np.arange(100, 103))
    decoder.feed(data[:30])
    assert decoder.pending_bytes == 12
    decoder.reset()
    assert decoder.pending_bytes == 0
    out = decoder.feed(data[36:])
    assert out.index.tolist() == [0] and out.rate[:, 0].tolist() == [2.0] and out.garbage_bytes == 0


def build_disturbed_stream(seed: int, with_temperature: bool, garbage_probability: float = 0.3):
    """Frames with garbage runs (rich in identifier bytes) and corrupted frames.

    Returns (stream, good sample raw values in order); the stream ends with
    two clean frames so that everything before them is decidable.
    """
    rng = np.random.default_rng(seed)
    layout = LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE
    n = int(rng.integers(5, 60))
    raw = rng.integers(-RAW_FULL_SCALE, RAW_FULL_SCALE, n)
    temp = rng.integers(-3000, 3000, (n, 3)) / 256.0 if with_temperature else None
    frames = bytearray(encode_frames(xyz(raw * LSB), np.arange(n), temp_c=temp))
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
    raw = np.rint(out.rate[:, 0] / LSB).astype(np.int64).tolist()
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
    assert np.rint(out.rate[:, 0] / LSB).astype(np.int64).tolist() == [s[0] for s in samples]
    assert (out.crc_errors, out.garbage_bytes) == (crc_errors, garbage)


def test_valid_frame_hidden_across_aligned_rows_still_wins():
    """Two rows that start with the identifier but hold garbage around a frame.

    Every row boundary carries 0x90, so only the check for CRC-valid frames
    inside failed rows can find the embedded frame.
    """
    hidden = encode_frames(xyz([5.0]), [3], latency_us=0x0090)
    assert hidden[13] == ID_RATE
    frames = encode_frames(xyz(np.arange(3.0)), np.arange(3))
    tail = encode_frames(xyz([6.0, 7.0]), [4, 5])
    # 0x90 + 4 bytes, then the hidden frame, then 13 zero bytes: the rows of 18 from the
    # first 0x90 start at 0x90 (prefix) and at hidden[13] (= 0x90), both failing the CRC.
    stream = frames + bytes([ID_RATE, 1, 2, 3, 4]) + hidden + bytes(13) + tail
    out = FrameDecoder().feed(stream)
    assert out.rate[:, 0].tolist() == [0.0, 1.0, 2.0, 5.0, 6.0, 7.0]
    assert out.garbage_bytes == 18 and out.crc_errors == 0
    assert reference_scan(stream, False)[1:] == (0, 18)


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
    assert np.rint(np.concatenate(parts)[:, 0] / LSB).astype(np.int64).tolist() == good
    assert (crc_errors, garbage) == (ref_crc, ref_garbage)


def test_large_clean_buffer_with_sparse_corruption_counts_exactly():
    n = 200_000
    rng = np.random.default_rng(7)
    raw = rng.integers(-RAW_FULL_SCALE, RAW_FULL_SCALE, n)
    frames = np.frombuffer(encode_frames(xyz(raw * LSB, 0.0, 0.0), np.arange(n)), dtype=np.uint8).reshape(n, LEN_90).copy()
    corrupt = np.sort(rng.choice(n - 2, 2000, replace=False))
    frames[corrupt, 3] ^= 0x5A
    out = FrameDecoder().feed(frames.tobytes())
    keep = np.ones(n, dtype=bool)
    keep[corrupt] = False
    assert np.array_equal(np.rint(out.rate[:, 0] / LSB).astype(np.int64), raw[keep])
    assert out.crc_errors == 2000 and out.garbage_bytes == 0
    assert out.lost_frames == 2000
    assert np.array_equal(out.index, np.flatnonzero(keep))
