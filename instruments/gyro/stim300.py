"""Driver for a STIM300-style gyro streaming datagrams over a serial line.

The unit streams continuously at its configured rate; the driver never sends
anything. It reads large chunks (whatever is waiting, at least what the
request still needs) and decodes them vectorised, so a 2 kHz stream costs a
handful of system calls and numpy calls per block, not a Python loop per
frame. Samples decoded beyond what was asked are kept for the next call,
so no good sample is ever dropped between blocks.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np
import serial

from gyrocal.instruments.errors import InstrumentConnectionError, InstrumentTimeout
from gyrocal.instruments.gyro.datagram import (
    DEFAULT_LSB,
    DecodedFrames,
    FrameDecoder,
    axis_index,
    flagged,
)
from gyrocal.instruments.interfaces import GyroBlock, Identity

_POLL_S = 0.05                  # longest single blocking read, so deadlines are honoured
_MAX_READ_BYTES = 4 << 20       # cap per read() so one call cannot hoard memory
_FLUSH_SETTLE_S = 0.02          # > a USB-serial adapter's latency timer (FTDI default 16 ms)


class Stim300Gyro:
    """``GyroStream`` over pyserial; ``port`` is a device path or a pyserial URL."""

    def __init__(
        self,
        port: str,
        baudrate: int = 921600,
        sample_rate_hz: float = 2000.0,
        with_temperature: bool = False,
        lsb: float = DEFAULT_LSB,
        timeout_s: float = 1.0,
        name: str = "gyro",
        axis: str = "x",
        crlf: bool = False,
    ) -> None:
        self.port = port
        self.name = name
        self.baudrate = int(baudrate)
        self.sample_rate_hz = float(sample_rate_hz)
        self.with_temperature = bool(with_temperature)
        self.lsb = float(lsb)
        self.timeout_s = float(timeout_s)
        self.axis = axis
        self._axis = axis_index(axis)
        self.crlf = bool(crlf)
        self._decoder = FrameDecoder(with_temperature=with_temperature, lsb=lsb, crlf=self.crlf)
        self._frame_length = self._decoder.layout.length
        try:
            self._serial = serial.serial_for_url(
                port, baudrate=self.baudrate, timeout=min(_POLL_S, self.timeout_s)
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise InstrumentConnectionError(name, f"open {port}", str(exc)) from exc
        self._reset_stream_state()

    # ------------------------------------------------------------------ GyroStream

    def identify(self) -> Identity:
        layout = self._decoder.layout
        return Identity(
            role="gyro",
            driver="stim300",
            address=self.port,
            description=(
                f"STIM300-style datagram 0x{layout.identifier:02X} ({layout.length}-byte frames), "
                f"{self.sample_rate_hz:g} Hz, lsb={self.lsb:g}, {self.baudrate} baud, "
                f"unit under test: {self.axis} axis{', CR LF' if self.crlf else ''}"
            ),
        )

    def flush(self) -> None:
        """Drop buffered bytes, the decoder's partial frame and any surplus samples.

        Bytes already in flight when the host buffer is flushed — in a
        USB-serial adapter's FIFO (released on its latency timer, 16 ms on
        FTDI parts) or in the kernel's tty flip buffers — arrive just after
        the flush and would be read as the first samples of the next step,
        though they describe the conditions before it. So the input is
        flushed, left for :data:`_FLUSH_SETTLE_S`, and flushed again.
        """
        try:
            self._serial.reset_input_buffer()
            time.sleep(_FLUSH_SETTLE_S)
            self._serial.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            raise InstrumentConnectionError(self.name, "flush", str(exc)) from exc
        self._decoder.reset()
        self._reset_stream_state()

    def read_samples(self, n: int, timeout_s: float | None = None) -> GyroBlock:
        """Return exactly ``n`` good samples, or raise ``InstrumentTimeout``.

        ``crc_errors`` and ``garbage_bytes`` are what was found in the bytes
        read for this block; ``lost_frames`` counts the counter gaps before
        this block's samples (since the previous block or the last flush).
        On timeout the samples already decoded are kept for the next call.
        """
        if n < 0:
            raise ValueError(f"{self.name}: read_samples: n must be >= 0, got {n}")
        timeout_s = self.timeout_s if timeout_s is None else float(timeout_s)
        command = f"read_samples(n={n}, timeout_s={timeout_s:g})"
        deadline = time.monotonic() + timeout_s
        while self._surplus_count < n:
            if time.monotonic() >= deadline:
                raise InstrumentTimeout(
                    self.name,
                    command,
                    f"received {self._surplus_count} of {n} samples within {timeout_s:g} s "
                    f"({self._pending_crc_errors} CRC errors, "
                    f"{self._pending_garbage_bytes} garbage bytes) on {self.port}",
                )
            self._read_chunk(n - self._surplus_count, command)
        return self._take(n)

    def close(self) -> None:
        with contextlib.suppress(serial.SerialException, OSError):
            self._serial.close()

    def __enter__(self) -> Stim300Gyro:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # ------------------------------------------------------------------ internals

    def _reset_stream_state(self) -> None:
        self._surplus: list[DecodedFrames] = []
        self._surplus_count = 0
        self._pending_crc_errors = 0
        self._pending_garbage_bytes = 0
        self._last_index_returned = -1

    def _read_chunk(self, samples_missing: int, command: str) -> None:
        wanted = samples_missing * self._frame_length - self._decoder.pending_bytes
        try:
            size = min(max(self._serial.in_waiting, wanted, 1), _MAX_READ_BYTES)
            chunk = self._serial.read(size)
        except (serial.SerialException, OSError) as exc:
            raise InstrumentConnectionError(self.name, command, f"read failed on {self.port}: {exc}") from exc
        if not chunk:
            return
        decoded = self._decoder.feed(chunk)
        self._pending_crc_errors += decoded.crc_errors
        self._pending_garbage_bytes += decoded.garbage_bytes
        if len(decoded):
            self._surplus.append(decoded)
            self._surplus_count += len(decoded)

    def _take(self, n: int) -> GyroBlock:
        parts = self._surplus
        rate = _concat([p.rate for p in parts], np.float64).reshape(-1, 3)
        status = _concat([p.status for p in parts], np.uint8)
        counter = _concat([p.counter for p in parts], np.uint8)
        index = _concat([p.index for p in parts], np.int64)
        latency = _concat([p.latency_us for p in parts], np.uint16)
        temp = temp_status = None
        if self.with_temperature:
            temp = _concat([p.temp_c for p in parts if p.temp_c is not None], np.float64).reshape(-1, 3)
            temp_status = _concat([p.temp_status for p in parts if p.temp_status is not None], np.uint8)

        if rate.shape[0] > n:
            rest = DecodedFrames(
                rate[n:], status[n:], counter[n:], index[n:], latency[n:],
                None if temp is None else temp[n:], None if temp_status is None else temp_status[n:],
            )
            self._surplus, self._surplus_count = [rest], rate.shape[0] - n
        else:
            self._surplus, self._surplus_count = [], 0

        index = index[:n]
        lost = 0
        if n:
            lost = int(index[-1] - self._last_index_returned) - n
            self._last_index_returned = int(index[-1])
        extra: dict = {"latency_us": latency[:n]}
        if temp is not None and temp_status is not None:
            extra["temperature_xyz_c"] = temp[:n]
            extra["temperature_status"] = temp_status[:n]
        block = GyroBlock(
            rate=rate[:n, self._axis],
            counter=counter[:n],
            index=index,
            status=status[:n],
            temperature_c=None if temp is None else temp[:n, self._axis],
            crc_errors=self._pending_crc_errors,
            lost_frames=lost,
            garbage_bytes=self._pending_garbage_bytes,
            extra=extra,
            rate_xyz=rate[:n],
            flagged=flagged(status[:n], self._axis),
        )
        self._pending_crc_errors = 0
        self._pending_garbage_bytes = 0
        return block


def _concat(arrays: list[np.ndarray], dtype: type) -> np.ndarray:
    if not arrays:
        return np.empty(0, dtype=dtype)
    if len(arrays) == 1:
        return arrays[0]
    return np.concatenate(arrays)
