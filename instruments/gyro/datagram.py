"""The STIM300-style single-axis gyro datagram: layout, vectorised encoder and decoder.

This module is the one place the wire format is defined. Everything else
(driver, simulator, tests) imports these constants.

Layout (all multi-byte fields big-endian)::

    0x90 frame, rate only, 12 bytes
      offset 0   identifier     0x90
      offset 1   rate           3 bytes, two's complement, raw LSB counts
      offset 4   status         1 byte  (0 = OK, bits below)
      offset 5   counter        1 byte, frame index modulo 256
      offset 6   latency_us     2 bytes, unsigned, sampling-to-transmit delay
      offset 8   crc            4 bytes, CRC-32/MPEG-2 of bytes 0..7

    0x94 frame, rate + temperature, 14 bytes
      offset 0   identifier     0x94
      offset 1   rate           3 bytes, two's complement
      offset 4   status         1 byte
      offset 5   temperature    2 bytes, two's complement, 1/256 °C per LSB
      offset 7   counter        1 byte
      offset 8   latency_us     2 bytes
      offset 10  crc            4 bytes, CRC-32/MPEG-2 of bytes 0..9

Rate scaling: ``rate = raw * lsb`` in the unit's output units; ``lsb`` is a
per-station setting (default 2**-14, the STIM300's deg/s LSB). A rate whose
raw value would exceed ±(2**23 − 1) is clipped to full scale and flagged
with :data:`STATUS_RATE_SATURATED` — never wrapped, because a wrapped sample
is a plausible-looking wrong number in a calibration. Same for temperature
with :data:`STATUS_TEMP_SATURATED`.

Decoding is vectorised over whole buffers (see :class:`FrameDecoder`): it is
equivalent to the byte-by-byte scanner

    at position i:
      identifier and CRC ok            -> frame, i += L
      identifier, CRC fails, and no
        CRC-valid frame starts inside
        (i, i + L)                     -> CRC error, i += L
      otherwise                        -> garbage byte, i += 1

so a stray identifier byte in garbage never costs a good frame (CRC-valid
frames win), corrupt frames are counted and never yield a sample, and every
byte of the stream is exactly one of: frame, CRC-error frame, garbage.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2_rows, crc32_mpeg2_words

ID_RATE = 0x90
ID_RATE_TEMP = 0x94

RAW_FULL_SCALE = 2**23 - 1
DEFAULT_LSB = 2.0**-14          # output units per LSB (deg/s on a STIM300)
TEMP_LSB_C = 1.0 / 256.0
TEMP_RAW_FULL_SCALE = 2**15 - 1

STATUS_OK = 0x00
STATUS_RATE_SATURATED = 0x01
STATUS_TEMP_SATURATED = 0x02

RATE_OFFSET = 1
STATUS_OFFSET = 4


@dataclass(frozen=True)
class FrameLayout:
    """Byte offsets of one frame type (see the module docstring)."""

    identifier: int
    length: int
    temp_offset: int | None
    counter_offset: int
    latency_offset: int
    crc_offset: int

    @property
    def with_temperature(self) -> bool:
        return self.temp_offset is not None


LAYOUT_RATE = FrameLayout(ID_RATE, 12, None, 5, 6, 8)
LAYOUT_RATE_TEMP = FrameLayout(ID_RATE_TEMP, 14, 5, 7, 8, 10)


def layout_for(with_temperature: bool) -> FrameLayout:
    return LAYOUT_RATE_TEMP if with_temperature else LAYOUT_RATE


# --------------------------------------------------------------------------- encode


def encode_frames(
    rate: np.ndarray,
    counter: np.ndarray,
    status: np.ndarray | None = None,
    temp_c: np.ndarray | None = None,
    latency_us: int | np.ndarray = 0,
    lsb: float = DEFAULT_LSB,
) -> bytes:
    """Encode samples into concatenated frames (0x94 if ``temp_c`` is given, else 0x90).

    ``counter`` is taken modulo 256, so the absolute frame index may be passed.
    Saturation bits are OR-ed into ``status``. NaN cannot be represented and
    raises ``ValueError`` naming the first offending sample.
    """
    frames = encode_frame_array(rate, counter, status, temp_c, latency_us, lsb)
    return frames.tobytes()


def encode_frame_array(
    rate: np.ndarray,
    counter: np.ndarray,
    status: np.ndarray | None = None,
    temp_c: np.ndarray | None = None,
    latency_us: int | np.ndarray = 0,
    lsb: float = DEFAULT_LSB,
) -> np.ndarray:
    """As :func:`encode_frames` but returns the (n_frames, frame_length) uint8 array.

    The simulator uses the array form to corrupt or drop individual frames.
    """
    if not lsb > 0:
        raise ValueError(f"lsb must be > 0, got {lsb!r}")
    rate = np.asarray(rate, dtype=np.float64).ravel()
    n = rate.shape[0]
    layout = layout_for(temp_c is not None)
    counter = np.broadcast_to(np.asarray(counter), (n,))
    status_out = np.zeros(n, np.uint8) if status is None else np.broadcast_to(
        np.asarray(status, dtype=np.uint8), (n,)).copy()
    latency = np.broadcast_to(np.asarray(latency_us), (n,))
    if latency.size and (latency.min() < 0 or latency.max() > 0xFFFF):
        raise ValueError("latency_us must be within 0..65535")

    raw_rate, rate_saturated = _to_raw(rate, lsb, RAW_FULL_SCALE, "rate")
    status_out[rate_saturated] |= STATUS_RATE_SATURATED

    frames = np.empty((n, layout.length), dtype=np.uint8)
    frames[:, 0] = layout.identifier
    raw_u32 = raw_rate.astype(np.int64) & 0xFFFFFF
    frames[:, 1] = raw_u32 >> 16
    frames[:, 2] = (raw_u32 >> 8) & 0xFF
    frames[:, 3] = raw_u32 & 0xFF
    if layout.temp_offset is not None:
        temp = np.broadcast_to(np.asarray(temp_c, dtype=np.float64), (n,))
        raw_temp, temp_saturated = _to_raw(temp / TEMP_LSB_C, 1.0, TEMP_RAW_FULL_SCALE, "temp_c")
        status_out[temp_saturated] |= STATUS_TEMP_SATURATED
        raw_t16 = raw_temp.astype(np.int64) & 0xFFFF
        frames[:, layout.temp_offset] = raw_t16 >> 8
        frames[:, layout.temp_offset + 1] = raw_t16 & 0xFF
    frames[:, STATUS_OFFSET] = status_out
    frames[:, layout.counter_offset] = np.asarray(counter, dtype=np.int64) & 0xFF
    latency64 = latency.astype(np.int64)
    frames[:, layout.latency_offset] = latency64 >> 8
    frames[:, layout.latency_offset + 1] = latency64 & 0xFF
    crc = crc32_mpeg2_rows(frames[:, : layout.crc_offset])
    for byte in range(4):
        frames[:, layout.crc_offset + byte] = (crc >> np.uint32(24 - 8 * byte)) & np.uint32(0xFF)
    return frames


def _to_raw(values: np.ndarray, lsb: float, full_scale: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Round to LSB counts, clip at ±full scale and say which samples were clipped."""
    bad = np.isnan(values)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}[{first}] is NaN: a datagram cannot carry it")
    with np.errstate(over="ignore", invalid="ignore"):
        scaled = np.rint(values / lsb)
    saturated = np.abs(scaled) > full_scale
    return np.clip(scaled, -full_scale, full_scale).astype(np.int32), saturated


# --------------------------------------------------------------------------- decode


@dataclass
class DecodedFrames:
    """Samples from frames whose CRC checked, in arrival order, plus what was dropped."""

    rate: np.ndarray            # float64, output units (raw * lsb)
    status: np.ndarray          # uint8
    counter: np.ndarray         # uint8
    index: np.ndarray           # int64, frames since decoder reset, counter gaps unwrapped
    latency_us: np.ndarray      # uint16
    temp_c: np.ndarray | None   # float64 (0x94 frames) or None
    crc_errors: int = 0         # frame-length spans that started with the identifier and failed CRC
    garbage_bytes: int = 0      # bytes skipped while re-synchronising
    lost_frames: int = 0        # frames missing according to counter gaps

    def __len__(self) -> int:
        return int(self.rate.shape[0])


class FrameDecoder:
    """Stateful vectorised decoder for one frame type.

    A station streams one configured datagram type, so the decoder accepts
    one identifier; frames of the other type are skipped as garbage. Bytes
    that cannot be decided yet (a partial trailing frame, or a failed
    candidate whose outcome depends on bytes not yet received) are kept for
    the next :meth:`feed`.
    """

    def __init__(self, with_temperature: bool = False, lsb: float = DEFAULT_LSB) -> None:
        if not lsb > 0:
            raise ValueError(f"lsb must be > 0, got {lsb!r}")
        self.layout = layout_for(with_temperature)
        self.lsb = float(lsb)
        self.total_frames = 0
        self.total_crc_errors = 0
        self.total_garbage_bytes = 0
        self.total_lost_frames = 0
        self.reset()

    def reset(self) -> None:
        """Forget the partial frame and the counter history (after a flush)."""
        self._carry = np.empty(0, dtype=np.uint8)
        self._last_counter: int | None = None
        self._last_index = -1

    @property
    def pending_bytes(self) -> int:
        """Bytes held back until more data arrives."""
        return int(self._carry.shape[0])

    def feed(self, data: bytes | bytearray | memoryview) -> DecodedFrames:
        """Decode everything decidable in ``pending + data``; keep the rest."""
        incoming = np.frombuffer(data, dtype=np.uint8)
        buf = np.concatenate([self._carry, incoming]) if self._carry.size else incoming
        layout = self.layout
        length = layout.length
        n = buf.shape[0]
        if n < length:
            self._carry = buf.copy()
            return self._empty()

        scan = self._scan_aligned(buf)
        if scan is None:
            scan = self._scan_general(buf)
        frames, n_crc_errors, cut = scan

        garbage = cut - length * (frames.shape[0] + n_crc_errors)
        self._carry = buf[cut:].copy()
        decoded = self._fields(_as_rows(frames, length))
        decoded.crc_errors = int(n_crc_errors)
        decoded.garbage_bytes = int(garbage)
        self.total_frames += len(decoded)
        self.total_crc_errors += decoded.crc_errors
        self.total_garbage_bytes += decoded.garbage_bytes
        self.total_lost_frames += decoded.lost_frames
        return decoded

    def _scan_general(self, buf: np.ndarray) -> tuple[np.ndarray, int, int]:
        """Any stream: every identifier byte is a candidate. Returns (frames, crc errors, cut)."""
        layout = self.layout
        length = layout.length
        n = buf.shape[0]
        cand = np.flatnonzero(buf[: n - length + 1] == layout.identifier)
        frames = _gather_frames(buf, cand, length)
        ok = _crc_ok(_as_rows(frames, length))
        if ok.all():
            valid = cand
        else:
            valid, frames = cand[ok], frames[ok]
        keep = _greedy_non_overlapping(valid, length)
        if keep is not None:
            valid, frames = valid[keep], frames[keep]

        failed = cand[~ok]
        crc_error_starts = self._crc_error_starts(failed, valid, n)
        end = 0
        if valid.size:
            end = int(valid[-1]) + length
        if crc_error_starts.size:
            end = max(end, int(crc_error_starts[-1]) + length)
        failed_after = failed[failed >= end]
        cut = int(failed_after[0]) if failed_after.size else max(end, n - length + 1)
        return frames, int(crc_error_starts.size), cut

    def _scan_aligned(self, buf: np.ndarray) -> tuple[np.ndarray, int, int] | None:
        """Fast path for the usual stream: frames back to back from the first identifier.

        The buffer is reshaped (no copy) into rows from the first identifier
        byte; if every row starts with the identifier, the CRC of all rows is
        checked at once. Rows failing the CRC are CRC errors provided no
        CRC-valid frame starts inside them (checked on those few rows only).
        Returns None whenever the general scan is needed (misalignment,
        garbage, a failed last row whose neighbourhood is incomplete).
        """
        layout = self.layout
        length = layout.length
        n = buf.shape[0]
        first = np.flatnonzero(buf[:length] == layout.identifier)
        if first.size == 0:
            return None
        p0 = int(first[0])
        m = (n - p0) // length
        if m == 0:
            return None
        rows = buf[p0 : p0 + m * length].reshape(m, length)
        if not (rows[:, 0] == layout.identifier).all():
            return None
        ok = _crc_ok(rows)
        frames = rows.view(f"V{length}").reshape(m)
        if ok.all():
            return frames, 0, p0 + m * length
        if not ok[-1]:
            return None
        failed = np.flatnonzero(~ok)
        inner = p0 + failed[:, None] * length + np.arange(1, length)   # starts inside failed rows
        inner = inner[buf[inner] == layout.identifier]
        if inner.size and inner.max() + length > n:
            return None
        if inner.size and _crc_ok(_as_rows(_gather_frames(buf, inner, length), length)).any():
            return None
        return frames[ok], int(failed.size), p0 + m * length

    def _crc_error_starts(self, failed: np.ndarray, valid: np.ndarray, n: int) -> np.ndarray:
        """Failed candidates that count as corrupt frames (see the module docstring).

        Only candidates whose whole neighbourhood has arrived are decided
        (``f + 2L - 1 <= n``): a CRC-valid frame may still start inside the
        span once more bytes arrive.
        """
        length = self.layout.length
        if failed.size == 0:
            return failed
        failed = failed[failed <= n - 2 * length + 1]
        if failed.size == 0 or valid.size == 0:
            eligible = failed
        else:
            after = np.searchsorted(valid, failed, side="right")
            next_valid = np.append(valid, np.iinfo(np.int64).max)[after]
            previous = after - 1
            previous_end = np.where(previous >= 0, valid[np.maximum(previous, 0)] + length, 0)
            eligible = failed[(next_valid >= failed + length) & (failed >= previous_end)]
        keep = _greedy_non_overlapping(eligible, length)
        return eligible if keep is None else eligible[keep]

    def _fields(self, rows: np.ndarray) -> DecodedFrames:
        layout = self.layout
        if rows.shape[0] == 0:
            return self._empty()
        words = rows.view(">u2")
        high = (words[:, 0].astype(np.uint32) << np.uint32(24)).view(np.int32) >> 8
        raw = high | words[:, 1].astype(np.int32)
        rate = raw * self.lsb
        status = rows[:, STATUS_OFFSET].copy()
        counter = rows[:, layout.counter_offset].copy()
        latency = words[:, layout.latency_offset // 2].astype(np.uint16)
        temp_c = None
        if layout.temp_offset is not None:
            t = layout.temp_offset
            raw_t = ((rows[:, t].astype(np.uint16) << np.uint16(8)) | rows[:, t + 1]).view(np.int16)
            temp_c = raw_t * TEMP_LSB_C
        index, lost = self._unwrap(counter)
        return DecodedFrames(rate, status, counter, index, latency, temp_c, lost_frames=lost)

    def _unwrap(self, counter: np.ndarray) -> tuple[np.ndarray, int]:
        """Frame index from the 8-bit counter; a step of 0 (mod 256) counts as 256 lost.

        A UART does not duplicate frames, so an unchanged counter can only
        mean a whole wrap went missing; gaps of 256 or more frames are not
        detectable from the counter alone (use the clock for that).
        """
        previous = (int(counter[0]) - 1) % 256 if self._last_counter is None else self._last_counter
        step8 = np.diff(counter, prepend=np.uint8(previous))   # uint8: wraps modulo 256
        self._last_counter = int(counter[-1])
        if (step8 == 1).all():
            index = np.arange(self._last_index + 1, self._last_index + 1 + counter.size, dtype=np.int64)
            self._last_index = int(index[-1])
            return index, 0
        step = step8.astype(np.int64)
        step[step == 0] = 256
        index = self._last_index + np.cumsum(step)
        self._last_index = int(index[-1])
        return index, int(step.sum()) - int(step.size)

    def _empty(self) -> DecodedFrames:
        empty_f = np.empty(0, np.float64)
        return DecodedFrames(
            rate=empty_f,
            status=np.empty(0, np.uint8),
            counter=np.empty(0, np.uint8),
            index=np.empty(0, np.int64),
            latency_us=np.empty(0, np.uint16),
            temp_c=empty_f.copy() if self.layout.with_temperature else None,
        )


def _gather_frames(buf: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """Frames starting at ``starts`` as a 1-D array of opaque ``V<length>`` items.

    One item per byte offset of ``buf`` (a strided view, no copy); gathering
    whole frames as single items is several times faster than a 2-D fancy index.
    """
    windows = np.ndarray(buffer=buf, dtype=f"V{length}", shape=(buf.shape[0] - length + 1,), strides=(1,))
    return windows[starts]


def _crc_ok(rows: np.ndarray) -> np.ndarray:
    """CRC check of each frame row (the CRC is the last 4 bytes, big-endian)."""
    words = rows.view(">u2")
    crc_word = words.shape[1] - 2
    stored = (words[:, crc_word].astype(np.uint32) << np.uint32(16)) | words[:, crc_word + 1]
    return crc32_mpeg2_words(words[:, :crc_word].astype(np.uint16)) == stored


def _as_rows(frames: np.ndarray, length: int) -> np.ndarray:
    """View a 1-D array of ``V<length>`` frames as an (n, length) uint8 array (no copy)."""
    return frames.view(np.uint8).reshape(-1, length)


def _greedy_non_overlapping(starts: np.ndarray, length: int) -> np.ndarray | None:
    """Leftmost chain of non-overlapping spans; None when all of them already fit.

    Overlaps among CRC-valid candidates need a 2**-32 coincidence, so the
    Python loop only runs on the rare conflicting buffers.
    """
    if starts.size < 2 or int(np.diff(starts).min()) >= length:
        return None
    keep = np.zeros(starts.size, dtype=bool)
    next_free = -1
    for i, start in enumerate(starts.tolist()):
        if start >= next_free:
            keep[i] = True
            next_free = start + length
    return keep
