"""STIM300 normal-mode datagrams: vectorised encoder and decoder (layouts in datagram_types.py).

Every normal-mode type of TS1524 rev 31 Table 5-21 (0x90–0x94, 0xA5–0xA7,
0xF0–0xF7) is handled; the byte layout of each comes from
:func:`~gyrocal.instruments.gyro.datagram_types.layout_of` (Table 5-20 order).
The tests build their expected bytes by hand from the datasheet tables
instead of importing the layouts.

Scaling (all fields big-endian two's complement unless said):

* rates: ``raw * lsb``; ``lsb`` is a station setting whose default 2**-14
  deg/s is the angular-rate output's LSB (§7.5.2.2.2, Equation 1, p. 49);
* accelerometers: LSB per range 5/10/30/80 g = 2**-20/-19/-18/-16 g
  (§7.5.2.2.7, Equation 3, p. 52); the range is a station setting;
* inclinometers: 2**-22 g (§7.5.2.2.11, Equation 5, p. 53);
* temperatures: 16 bit, 1/256 °C (§7.5.2.2.17, Equation 9, p. 55);
* counter: unsigned byte counting the internal 2000 Hz samples
  (§7.5.2.2.18, p. 55), so it steps 2000/fs per datagram: the decoder
  unwraps it into a datagram index with that step (``counter_step``);
* latency: unsigned 16 bit, µs (§7.5.2.2.19, p. 55).

CRC rule (§5.5.7, p. 37; Table 5-22, p. 38): CRC-32 (poly 0x04C11DB7, init
0xFFFFFFFF, MSB first, no final XOR) over the datagram from the identifier
up to the CRC, padded with dummy 0x00 bytes to a whole number of 32-bit
words. The unit may be set to append CR LF (``crlf=True``), outside the CRC.

Status bytes (Table 5-23, p. 38), bit 7 first: 7 system integrity error,
6 start-up, 5 outside operating conditions, 4 overload, 3 error in
measurement channel, 2/1/0 the z/y/x channel the overload or error refers
to. Each sensor cluster has its own status byte. The encoder never wraps an
out-of-range value: it clips it to full scale and sets overload + the axis
bit, because a wrapped sample is a plausible-looking wrong number.

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
With CR LF termination a frame is only valid if its terminator is intact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro import crc32_mpeg2, field_packing
from gyrocal.instruments.gyro.channels import SensorChannels, concat_channels
from gyrocal.instruments.gyro.crc32_mpeg2 import crc32_mpeg2_prefix_rows
from gyrocal.instruments.gyro.datagram_types import (  # noqa: F401 - re-exported for the driver, sim and tests
    ACCELEROMETER_LSB_G,
    DEFAULT_ACCELEROMETER_RANGE_G,
    ID_RATE,
    ID_RATE_TEMP,
    INCLINOMETER_LSB_G,
    LAYOUT_RATE,
    LAYOUT_RATE_TEMP,
    RATE_OFFSET,
    STATUS_OFFSET,
    FrameLayout,
    counter_values,
    frames_per_counter_step,
    layout_for,
    layout_of,
)

AXES = ("x", "y", "z")
RAW_FULL_SCALE = 2**23 - 1
DEFAULT_LSB = 2.0**-14          # deg/s per LSB, STIM300 ±400 deg/s range
TEMP_LSB_C = 1.0 / 256.0
TEMP_RAW_FULL_SCALE = 2**15 - 1

STATUS_AXIS_X = 0x01
STATUS_AXIS_Y = 0x02
STATUS_AXIS_Z = 0x04
STATUS_CHANNEL_ERROR = 0x08
STATUS_OVERLOAD = 0x10
STATUS_OUTSIDE_OPERATING = 0x20
STATUS_STARTUP = 0x40
STATUS_SYSTEM_INTEGRITY = 0x80
STATUS_AXIS_BITS = (STATUS_AXIS_X, STATUS_AXIS_Y, STATUS_AXIS_Z)
STATUS_WHOLE_UNIT = STATUS_SYSTEM_INTEGRITY | STATUS_STARTUP | STATUS_OUTSIDE_OPERATING
STATUS_CHANNEL_FLAGS = STATUS_OVERLOAD | STATUS_CHANNEL_ERROR


def axis_index(axis: str) -> int:
    """0, 1, 2 for ``x``, ``y``, ``z`` (the station file's ``axis:``)."""
    try:
        return AXES.index(axis)
    except ValueError:
        raise ValueError(f"axis must be one of x, y, z, got {axis!r}") from None


def flagged(status: np.ndarray, axis: int) -> np.ndarray:
    """Samples the status byte marks as not valid for ``axis`` (bool array).

    Whole-unit conditions (system integrity, start-up, outside operating
    conditions) flag every axis. Overload / channel error flag the axes
    whose bit is set; with no axis bit set they are taken to mean all axes
    (the conservative reading: a calibration must not keep a doubtful sample).
    """
    status = np.asarray(status, dtype=np.uint8)
    axis_bits = status & np.uint8(0x07)
    channel = (status & np.uint8(STATUS_CHANNEL_FLAGS)) != 0
    this_axis = ((axis_bits & np.uint8(STATUS_AXIS_BITS[axis])) != 0) | (axis_bits == 0)
    return ((status & np.uint8(STATUS_WHOLE_UNIT)) != 0) | (channel & this_axis)


def frame_crc(rows: np.ndarray, layout: FrameLayout) -> np.ndarray:
    """CRC of each datagram row under the dummy-byte rule (uint32 per row)."""
    return crc32_mpeg2_prefix_rows(rows, layout.crc_offset, layout.crc_dummy_bytes)


# --------------------------------------------------------------------------- encode


def encode_frames(
    rate: np.ndarray,
    counter: np.ndarray,
    status: np.ndarray | None = None,
    temp_c: np.ndarray | None = None,
    latency_us: int | np.ndarray = 0,
    lsb: float = DEFAULT_LSB,
    crlf: bool = False,
    *,
    datagram: int | None = None,
    channels: SensorChannels | None = None,
    accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G,
) -> bytes:
    """Encode samples into concatenated datagrams (see :func:`encode_frame_array`)."""
    return encode_frame_array(rate, counter, status, temp_c, latency_us, lsb, crlf,
                              datagram=datagram, channels=channels,
                              accelerometer_range_g=accelerometer_range_g).tobytes()


def encode_frame_array(
    rate: np.ndarray,
    counter: np.ndarray,
    status: np.ndarray | None = None,
    temp_c: np.ndarray | None = None,
    latency_us: int | np.ndarray = 0,
    lsb: float = DEFAULT_LSB,
    crlf: bool = False,
    *,
    datagram: int | None = None,
    channels: SensorChannels | None = None,
    accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G,
) -> np.ndarray:
    """Datagrams as an (n_frames, frame_length) uint8 array (the simulator corrupts rows of it).

    ``datagram`` is the identifier (Table 5-21); without it 0x94 if
    ``temp_c`` is given, else 0x90. ``rate`` is (n, 3) x/y/z; ``temp_c``
    the gyro temperatures, (n, 3) or broadcastable, also used for the other
    clusters' temperatures that ``channels`` does not give. ``channels``
    gives accelerometers and inclinometers (g) and their statuses, where the
    type carries them (zeros when not given). ``counter`` is taken modulo
    256 (pass :func:`counter_values` of the frame index for the datasheet's
    step). Clipping sets overload + the axis bit in that cluster's status.
    NaN cannot be represented and raises ``ValueError``.
    """
    if not lsb > 0:
        raise ValueError(f"lsb must be > 0, got {lsb!r}")
    rate = np.asarray(rate, dtype=np.float64)
    if rate.ndim != 2 or rate.shape[1] != 3:
        raise ValueError(f"rate must have shape (n, 3) (x, y, z), got {rate.shape}")
    n = rate.shape[0]
    layout = layout_for(temp_c is not None, crlf) if datagram is None else layout_of(datagram, crlf)
    channels = channels if channels is not None else SensorChannels()
    latency = np.broadcast_to(np.asarray(latency_us), (n,))
    if latency.size and (latency.min() < 0 or latency.max() > 0xFFFF):
        raise ValueError("latency_us must be within 0..65535")

    frames = np.empty((n, layout.length), dtype=np.uint8)
    frames[:, 0] = layout.identifier
    _put_triplet(frames, RATE_OFFSET, STATUS_OFFSET, rate / lsb, status, RAW_FULL_SCALE, 3, "rate")
    _put_channels(frames, layout, channels, temp_c, accelerometer_range_g)
    frames[:, layout.counter_offset] = np.broadcast_to(np.asarray(counter, dtype=np.int64), (n,)) & 0xFF
    _put_int(frames, layout.latency_offset, latency.astype(np.int64)[:, None], 2)
    crc = frame_crc(frames, layout)
    for byte in range(4):
        frames[:, layout.crc_offset + byte] = (crc >> np.uint32(24 - 8 * byte)) & np.uint32(0xFF)
    if layout.crlf:
        frames[:, -2] = 0x0D
        frames[:, -1] = 0x0A
    return frames


def _put_channels(frames: np.ndarray, layout: FrameLayout, channels: SensorChannels,
                  temp_c: np.ndarray | None, accelerometer_range_g: int) -> None:
    """Accelerometers, inclinometers, temperatures and PPS, where ``layout`` has them."""
    n = frames.shape[0]
    acc_lsb = accelerometer_lsb_g(accelerometer_range_g)
    for offset, status_offset, values, cluster_status, lsb_g, what in (
        (layout.acc_offset, layout.acc_status_offset, channels.acc_g, channels.acc_status, acc_lsb, "acc_g"),
        (layout.incl_offset, layout.incl_status_offset, channels.incl_g, channels.incl_status,
         INCLINOMETER_LSB_G, "incl_g"),
    ):
        if offset is not None and status_offset is not None:
            scaled = np.zeros((n, 3)) if values is None else _as_xyz(values, n) / lsb_g
            _put_triplet(frames, offset, status_offset, scaled, cluster_status, RAW_FULL_SCALE, 3, what)
    for offset, status_offset, values in (
        (layout.temp_offset, layout.temp_status_offset, channels.gyro_temp_c),
        (layout.acc_temp_offset, layout.acc_temp_status_offset, channels.acc_temp_c),
        (layout.incl_temp_offset, layout.incl_temp_status_offset, channels.incl_temp_c),
    ):
        if offset is not None and status_offset is not None:
            values = values if values is not None else temp_c
            if values is None:
                raise ValueError(f"datagram 0x{layout.identifier:02X} carries temperatures: give temp_c")
            _put_triplet(frames, offset, status_offset, _as_xyz(values, n) / TEMP_LSB_C, None,
                         TEMP_RAW_FULL_SCALE, 2, "temp_c")
    if layout.pps_offset is not None and layout.pps_status_offset is not None:
        pps = np.zeros(n) if channels.pps is None else np.broadcast_to(channels.pps, (n,))
        _put_int(frames, layout.pps_offset, np.asarray(pps, dtype=np.int64)[:, None], 3)
        frames[:, layout.pps_status_offset] = 0 if channels.pps_status is None else channels.pps_status


def accelerometer_lsb_g(range_g: int) -> float:
    """g per LSB of the accelerometers at ``range_g`` (§7.5.2.2.7, p. 52)."""
    try:
        return ACCELEROMETER_LSB_G[int(range_g)]
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"accelerometer range must be one of "
                         f"{', '.join(str(r) for r in ACCELEROMETER_LSB_G)} g, got {range_g!r}") from None


def _as_xyz(values: np.ndarray, n: int) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    return np.broadcast_to(values.reshape(-1, 3) if values.ndim == 2 else values.reshape(-1, 1), (n, 3))


#: pack and unpack fields with the compiled loops (field_packing.py); the numpy here is
#: their oracle
_COMPILED = field_packing.AVAILABLE


def _put_triplet(frames: np.ndarray, offset: int, status_offset: int, scaled: np.ndarray,
                 status: np.ndarray | None, full_scale: int, width: int, what: str) -> None:
    """x, y, z fields of ``width`` bytes and their status byte (overload bits on clipping)."""
    n = frames.shape[0]
    status_out = np.zeros(n, np.uint8) if status is None else np.broadcast_to(
        np.asarray(status, dtype=np.uint8), (n,)).copy()
    if _COMPILED and scaled.shape[1:] == (len(STATUS_AXIS_BITS),):
        first_nan = field_packing.pack_triplet(frames, offset, status_offset, scaled, status_out,
                                               full_scale, width, STATUS_AXIS_BITS, STATUS_OVERLOAD)
        if first_nan >= 0:
            raise ValueError(f"{what}[{first_nan}] is NaN: a datagram cannot carry it")
        return
    raw, saturated = _to_raw(scaled, full_scale, what)
    status_out |= _overload_bits(saturated)
    _put_int(frames, offset, raw, width)
    frames[:, status_offset] = status_out


def _put_int(frames: np.ndarray, offset: int, values: np.ndarray, width: int) -> None:
    """Write the columns of ``values`` as consecutive big-endian ``width``-byte fields."""
    if _COMPILED:
        field_packing.pack_ints(frames, offset, values, width)
        return
    mask = (1 << (8 * width)) - 1
    # big-endian 32-bit words whose low ``width`` bytes are the fields: one strided copy per
    # byte position for all columns (a shift and mask per byte and column cost ~3x more)
    words = np.ascontiguousarray(values.astype(np.int64) & mask, dtype=">u4").view(np.uint8).reshape(
        values.shape[0], -1, 4)
    stop = offset + words.shape[1] * width
    for byte in range(width):
        frames[:, offset + byte : stop : width] = words[:, :, 4 - width + byte]


def _overload_bits(saturated: np.ndarray) -> np.ndarray:
    """Status bits for clipped channels: overload plus the bit of each clipped axis."""
    bits = np.zeros(saturated.shape[0], np.uint8)
    for axis, axis_bit in enumerate(STATUS_AXIS_BITS):
        bits[saturated[:, axis]] |= np.uint8(STATUS_OVERLOAD | axis_bit)
    return bits


def _to_raw(scaled: np.ndarray, full_scale: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Round to LSB counts, clip at ±full scale and say which samples were clipped."""
    bad = np.isnan(scaled)
    if bad.any():
        first = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValueError(f"{what}[{first}] is NaN: a datagram cannot carry it")
    with np.errstate(over="ignore", invalid="ignore"):
        rounded = np.rint(scaled)
    saturated = np.abs(rounded) > full_scale
    return np.clip(rounded, -full_scale, full_scale).astype(np.int32), saturated


# --------------------------------------------------------------------------- decode


@dataclass
class DecodedFrames:
    """Samples from frames whose CRC checked, in arrival order, plus what was dropped."""

    rate: np.ndarray            # float64 (n, 3) x, y, z in output units (raw * lsb)
    status: np.ndarray          # uint8 status byte of the rates
    counter: np.ndarray         # uint8
    index: np.ndarray           # int64, datagrams since decoder reset, counter gaps unwrapped
    latency_us: np.ndarray      # uint16
    temp_c: np.ndarray | None   # float64 (n, 3) gyro temperatures, or None (no temperature)
    temp_status: np.ndarray | None = None   # uint8 gyro temperature status, or None
    crc_errors: int = 0         # frame-length spans that started with the identifier and failed CRC
    garbage_bytes: int = 0      # bytes skipped while re-synchronising
    lost_frames: int = 0        # datagrams missing according to counter gaps
    channels: SensorChannels | None = None   # accelerometers, inclinometers, other temperatures

    def __len__(self) -> int:
        return int(self.rate.shape[0])

    def sliced(self, selection: slice) -> DecodedFrames:
        """Rows ``selection`` (counts of dropped frames are not carried)."""
        return DecodedFrames(
            self.rate[selection], self.status[selection], self.counter[selection],
            self.index[selection], self.latency_us[selection],
            None if self.temp_c is None else self.temp_c[selection],
            None if self.temp_status is None else self.temp_status[selection],
            channels=None if self.channels is None else self.channels.sliced(selection))


class FrameDecoder:
    """Stateful vectorised decoder for one frame type.

    A station streams one configured datagram type, so the decoder accepts
    one identifier (``datagram``; without it 0x94 or 0x90 by
    ``with_temperature``); frames of other types are skipped as garbage.
    ``counter_step`` is the counter's advance per datagram (2000 / fs,
    ``datagram_types.counter_step``). Bytes that cannot be decided yet (a partial
    trailing frame, or a failed candidate whose outcome depends on bytes not
    yet received) are kept for the next :meth:`feed`.
    """

    def __init__(self, with_temperature: bool = False, lsb: float = DEFAULT_LSB, crlf: bool = False,
                 *, datagram: int | None = None, counter_step: int = 1,
                 accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G) -> None:
        if not lsb > 0:
            raise ValueError(f"lsb must be > 0, got {lsb!r}")
        if not 1 <= int(counter_step) <= 255:
            raise ValueError(f"counter_step must be within 1..255, got {counter_step!r}")
        self.layout = layout_for(with_temperature, crlf) if datagram is None else layout_of(datagram, crlf)
        crc32_mpeg2.warm_up()      # the compiled CRC, before the first (timed) read
        field_packing.warm_up()    # and the compiled field reads
        self.lsb = float(lsb)
        self.acc_lsb_g = accelerometer_lsb_g(accelerometer_range_g)
        self.counter_step = int(counter_step)
        self._frames_per_step = np.asarray(frames_per_counter_step(self.counter_step), dtype=np.int64)
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
        ok = _crc_ok(_as_rows(frames, length), layout)
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
        ok = _crc_ok(rows, layout)
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
        if inner.size and _crc_ok(_as_rows(_gather_frames(buf, inner, length), length), layout).any():
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
        rate = _get_int(rows, RATE_OFFSET, 3, 3) * self.lsb
        status = rows[:, STATUS_OFFSET].copy()
        counter = rows[:, layout.counter_offset].copy()
        latency = _get_int(rows, layout.latency_offset, 1, 2, signed=False)[:, 0].astype(np.uint16)
        temp_c, temp_status = _cluster(rows, layout.temp_offset, layout.temp_status_offset, 2, TEMP_LSB_C)
        acc_g, acc_status = _cluster(rows, layout.acc_offset, layout.acc_status_offset, 3, self.acc_lsb_g)
        incl_g, incl_status = _cluster(rows, layout.incl_offset, layout.incl_status_offset, 3,
                                       INCLINOMETER_LSB_G)
        acc_t, acc_t_status = _cluster(rows, layout.acc_temp_offset, layout.acc_temp_status_offset, 2,
                                       TEMP_LSB_C)
        incl_t, incl_t_status = _cluster(rows, layout.incl_temp_offset, layout.incl_temp_status_offset,
                                         2, TEMP_LSB_C)
        pps = pps_status = None
        if layout.pps_offset is not None and layout.pps_status_offset is not None:
            pps = _get_int(rows, layout.pps_offset, 1, 3)[:, 0]
            pps_status = rows[:, layout.pps_status_offset].copy()
        channels = SensorChannels(acc_g, acc_status, incl_g, incl_status, temp_c, temp_status,
                                  acc_t, acc_t_status, incl_t, incl_t_status, pps, pps_status)
        index, lost = self._unwrap(counter)
        return DecodedFrames(rate, status, counter, index, latency, temp_c, temp_status, lost_frames=lost,
                             channels=channels)

    def _unwrap(self, counter: np.ndarray) -> tuple[np.ndarray, int]:
        """Datagram index from the 8-bit counter, which advances ``counter_step`` per datagram.

        A step other than ``counter_step`` spans the smallest whole number of
        datagrams that gives it (:func:`frames_per_counter_step`); an unchanged
        counter therefore means a whole wrap (256 / step datagrams) went
        missing, since a UART does not duplicate frames. Longer gaps are not
        detectable from the counter alone (use the clock for that).
        """
        step_ticks = self.counter_step
        previous = (int(counter[0]) - step_ticks) % 256 if self._last_counter is None else self._last_counter
        step8 = np.diff(counter, prepend=np.uint8(previous))   # uint8: wraps modulo 256
        self._last_counter = int(counter[-1])
        if (step8 == step_ticks).all():
            index = np.arange(self._last_index + 1, self._last_index + 1 + counter.size, dtype=np.int64)
            self._last_index = int(index[-1])
            return index, 0
        step = self._frames_per_step[step8]
        index = self._last_index + np.cumsum(step)
        self._last_index = int(index[-1])
        return index, int(step.sum()) - int(step.size)

    def _empty(self) -> DecodedFrames:
        return _empty_frames(self.layout)


def _empty_frames(layout: FrameLayout) -> DecodedFrames:
    """No samples, with the fields ``layout`` carries present (empty) and the others None."""
    def triplet(offset: int | None) -> tuple[np.ndarray | None, np.ndarray | None]:
        if offset is None:
            return None, None
        return np.empty((0, 3), np.float64), np.empty(0, np.uint8)

    temp_c, temp_status = triplet(layout.temp_offset)
    pps = None if layout.pps_offset is None else np.empty(0, np.int64)
    channels = SensorChannels(*triplet(layout.acc_offset), *triplet(layout.incl_offset), temp_c, temp_status,
                              *triplet(layout.acc_temp_offset), *triplet(layout.incl_temp_offset),
                              pps, None if pps is None else np.empty(0, np.uint8))
    return DecodedFrames(
        rate=np.empty((0, 3), np.float64),
        status=np.empty(0, np.uint8),
        counter=np.empty(0, np.uint8),
        index=np.empty(0, np.int64),
        latency_us=np.empty(0, np.uint16),
        temp_c=temp_c,
        temp_status=temp_status,
        channels=channels,
    )


def concat_decoded(parts: list[DecodedFrames], layout: FrameLayout) -> DecodedFrames:
    """Decoded blocks joined in order (empty, with ``layout``'s fields, when there are none)."""
    if not parts:
        return _empty_frames(layout)
    if len(parts) == 1:
        return parts[0]

    def joined(name: str) -> np.ndarray | None:
        arrays = [getattr(p, name) for p in parts]
        return None if arrays[0] is None else np.concatenate(arrays)

    channels = [p.channels for p in parts if p.channels is not None]
    return DecodedFrames(
        joined("rate"), joined("status"), joined("counter"), joined("index"), joined("latency_us"),
        joined("temp_c"), joined("temp_status"),
        channels=concat_channels(channels) if len(channels) == len(parts) else None)


def _cluster(rows: np.ndarray, offset: int | None, status_offset: int | None, width: int,
             lsb: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """x, y, z of one sensor cluster scaled by ``lsb``, and its status byte (None if absent)."""
    if offset is None or status_offset is None:
        return None, None
    return _get_int(rows, offset, 3, width) * lsb, rows[:, status_offset].copy()


def _get_int(rows: np.ndarray, offset: int, count: int, width: int, signed: bool = True) -> np.ndarray:
    """``count`` consecutive big-endian ``width``-byte fields from ``offset`` as int64 columns."""
    if _COMPILED and rows.dtype == np.uint8 and rows.ndim == 2:
        return field_packing.unpack_ints(rows, offset, count, width, signed)
    words = np.zeros((rows.shape[0], count, 4), dtype=np.uint8)   # big-endian 32-bit words
    stop = offset + count * width
    for byte in range(width):
        words[:, :, 4 - width + byte] = rows[:, offset + byte : stop : width]
    out = words.view(">u4")[:, :, 0].astype(np.int64)
    if signed:
        sign = np.int64(1) << np.int64(8 * width - 1)
        out = (out ^ sign) - sign
    return out


def _gather_frames(buf: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """Frames starting at ``starts`` as a 1-D array of opaque ``V<length>`` items.

    One item per byte offset of ``buf`` (a strided view, no copy); gathering
    whole frames as single items is several times faster than a 2-D fancy index.
    """
    windows = np.ndarray(buffer=buf, dtype=f"V{length}", shape=(buf.shape[0] - length + 1,), strides=(1,))
    return windows[starts]


def _crc_ok(rows: np.ndarray, layout: FrameLayout) -> np.ndarray:
    """Validity of each datagram row: CRC under the dummy-byte rule, and the CR LF if configured."""
    c = layout.crc_offset
    stored = ((rows[:, c].astype(np.uint32) << np.uint32(24)) | (rows[:, c + 1].astype(np.uint32) << np.uint32(16))
              | (rows[:, c + 2].astype(np.uint32) << np.uint32(8)) | rows[:, c + 3])
    ok = frame_crc(rows, layout) == stored
    if layout.crlf:
        ok &= (rows[:, -2] == 0x0D) & (rows[:, -1] == 0x0A)
    return ok


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
