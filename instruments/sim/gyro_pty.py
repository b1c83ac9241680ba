"""A simulated STIM300 streaming its declared datagram type into a pseudo-terminal.

The driver opens ``port_name`` exactly as it would open ``/dev/ttyUSB0``, so
the same serial code path (pyserial, termios, select, partial reads) is
exercised in dry runs and tests.

Frames lie on an absolute grid ``t_k = k / sample_rate_hz`` with the
datasheet's counter, ``k · 2000 / fs mod 256`` (gyro_frames.py says what a
frame holds). Time follows the shared clock:

* ``RealClock`` (any speed): the stream starts at the current time; a block
  is written once the clock has reached its end time (paced like the real
  instrument, ``speed`` times faster in wall time). A real unit sends each
  frame as it samples it, so on a real clock a block spans at most
  :data:`_REAL_BLOCK_WALL_S` of wall time: a 512-frame block (1 s of clock at
  500 Hz) would hand the reader frames a second old the moment it flushed.
  A real unit never waits for its reader either: a frame more than
  :data:`_REAL_MAX_LAG_S` of clock time older than the clock (a writer
  starved of CPU on a loaded host for longer than a serial port's input
  queue would hold) is dropped (a counter gap, which the reader counts).
* Any clock: the reader's input flush is honoured as on a real serial port.
  The master runs in packet mode (``TIOCPKT``), so the writer learns when
  the reader flushes its input queue; a frame sampled before that moment
  would have been in the flushed queue, so it is never written afterwards
  (issue 28: a writer behind the clock on a loaded host handed the reader,
  just after its flush, frames sampled while the table was still
  accelerating — the first 80-90 samples of a dwell, SF 1000-3000 ppm off).
* ``SimClock``: time moves as fast as the consumer reads. Before producing a
  block the writer jumps forward if someone else advanced the clock past it
  (those frames were never read by anybody, so they appear as a counter
  gap), writes the block — blocking while the pty buffer is full, which is
  the back-pressure that keeps the gyro from running ahead of its reader —
  and then advances the clock to the end of the block.

Faults (armed on the :class:`FaultInjector`; see :data:`FAULTS`):

* ``corrupt_frames``: each firing flips one payload byte of one frame (CRC fails).
* ``lose_frames``: each firing omits one frame (counter gap).
* ``saturate``: each firing sends one frame whose unit-under-test axis is at
  positive full scale; the encoder sets overload + that axis bit.
* ``garbage``: each firing inserts ``n_bytes`` (param, default 32) random
  bytes before the next block.
* ``stall``: stop sending for ``duration_s`` wall seconds (param), or while
  it stays armed when no duration is given.

What was injected is tallied in :attr:`SimulatedGyroPort.injected` so tests
can compare it with what the driver counted.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import math
import os
import select
import struct
import termios
import threading
import tty
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.gyro.datagram import (
    DEFAULT_ACCELEROMETER_RANGE_G,
    DEFAULT_LSB,
    RATE_OFFSET,
    RAW_FULL_SCALE,
    layout_for,
    layout_of,
)
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.gyro_frames import SpecificForceSource, encode_sim_frames
from gyrocal.models.clock import RealClock, SimClock

FAULTS = ("corrupt_frames", "lose_frames", "garbage", "stall", "saturate")

#: frame times → (rate: (n,) for a single-axis gyro or (n, 3) for an IMU, temperature or None)
GyroSource = Callable[[np.ndarray], tuple[np.ndarray, "np.ndarray | None"]]

_POLL_S = 0.05          # how often blocking waits look at the stop flag
_REAL_BLOCK_WALL_S = 0.01      # real clock: a block spans at most this much wall time
_REAL_MAX_LAG_S = 2.0          # real clock: frames older than this (clock s) behind the clock are dropped
_EPS_FRAMES = 1e-6      # tolerance when converting clock time to a frame number


class SimulatedGyroPort:
    """Streams datagrams from ``source`` into a pty; the driver opens :attr:`port_name`."""

    def __init__(
        self,
        source: GyroSource,
        clock: RealClock | SimClock,
        sample_rate_hz: float = 2000.0,
        with_temperature: bool = False,
        lsb: float = DEFAULT_LSB,
        faults: FaultInjector | None = None,
        block_frames: int = 256,
        latency_us: int = 250,
        seed: int = 0,
        axis: int = 0,
        crlf: bool = False,
        datagram: int | None = None,
        accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G,
        specific_force: SpecificForceSource | None = None,
    ) -> None:
        if not sample_rate_hz > 0:
            raise ValueError(f"sample_rate_hz must be > 0, got {sample_rate_hz!r}")
        if block_frames < 1:
            raise ValueError(f"block_frames must be >= 1, got {block_frames!r}")
        self.source = source
        self.clock = clock
        self.sample_rate_hz = float(sample_rate_hz)
        # the declared datagram type (TS1524 Table 5-21); without one 0x94 / 0x90
        self.layout = layout_for(with_temperature, crlf) if datagram is None else layout_of(datagram, crlf)
        self.with_temperature = self.layout.with_temperature
        self.accelerometer_range_g = int(accelerometer_range_g)
        # an IMU's accelerometers (imu_source.py); None: level and at rest, +1 g on z
        self.specific_force = specific_force
        self.crlf = bool(crlf)
        self.axis = int(axis)       # the simulated unit is single-axis: its output on this axis, 0 on the others
        self.lsb = float(lsb)
        self.faults = faults if faults is not None else FaultInjector(FAULTS, owner="simulated gyro")
        self.block_frames = int(block_frames)
        self.latency_us = int(latency_us)
        self._rng = np.random.default_rng(seed)
        self.injected = {
            "corrupt_frames": 0, "lose_frames": 0, "garbage_bytes": 0, "saturate": 0, "stalls": 0,
        }
        self.frames_written = 0         # frames fully handed to the pty
        self.next_frame = 0             # k of the next frame to produce
        self.error: BaseException | None = None   # what ended the writer thread, if anything
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._master_fd, self._slave_fd = os.openpty()
        tty.setraw(self._slave_fd)
        os.set_blocking(self._master_fd, False)
        # packet mode: the master reads a status byte when the reader flushes its input
        fcntl.ioctl(self._master_fd, termios.TIOCPKT, struct.pack("i", 1))
        self._flushed_k = -(2**62)      # frames before this one were flushed by the reader
        self.port_name = os.ttyname(self._slave_fd)
        self._closed = False

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> SimulatedGyroPort:
        if self._closed:
            raise RuntimeError("simulated gyro: cannot start after stop()")
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="sim-gyro-pty", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the writer, join it and close both pty ends (safe to call twice)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if not self._closed:
            self._closed = True
            for fd in (self._master_fd, self._slave_fd):
                with contextlib.suppress(OSError):
                    os.close(fd)

    @property
    def running(self) -> bool:
        """True while the writer thread is alive (it ends on stop() or on an error)."""
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self) -> SimulatedGyroPort:
        return self.start()

    def __exit__(self, *exc_info) -> None:
        self.stop()

    # ------------------------------------------------------------------ writer

    def _run(self) -> None:
        # Start at the current time: a session clock may have run for hours,
        # and a real gyro does not replay the frames from before it was on.
        k_now = math.floor(self.clock.now_s() * self.sample_rate_hz + _EPS_FRAMES)
        self.next_frame = max(self.next_frame, k_now)
        try:
            while not self._stop.is_set():
                if self._stalled():
                    continue
                self._produce_block()
        except BaseException as exc:  # noqa: BLE001 - reported through .error, thread must end
            if not self._stop.is_set():
                self.error = exc

    def _stalled(self) -> bool:
        """Honour an armed ``stall``; True if the writer waited (loop again)."""
        params = self.faults.params("stall")
        if params is None:
            return False
        if "duration_s" in params:
            self.faults.take("stall")
            self.injected["stalls"] += 1
            self._stop.wait(float(params["duration_s"]))
        else:
            self._stop.wait(_POLL_S)
        return True

    def _real_frames(self, wall_s: float) -> int:
        """Frames of ``wall_s`` wall seconds on a real clock (at least one)."""
        speed = self.clock.speed if isinstance(self.clock, RealClock) else 1.0
        return max(1, int(wall_s * speed * self.sample_rate_hz))

    def _max_lag_frames(self) -> int:
        return max(1, int(_REAL_MAX_LAG_S * self.sample_rate_hz))

    def _note_flush(self) -> int:
        """Read the master's packet-mode status; the first frame not flushed by the reader.

        A ``TIOCPKT_FLUSHREAD`` status means the reader discarded its input
        queue: every frame sampled before now would have been discarded with
        it, so none of them may be written after it.
        """
        readable, _, _ = select.select([self._master_fd], [], [], 0)
        if readable:
            with contextlib.suppress(BlockingIOError):
                status = os.read(self._master_fd, 4096)
                if status and status[0] & termios.TIOCPKT_FLUSHREAD:
                    self._flushed_k = math.ceil(self.clock.now_s() * self.sample_rate_hz - _EPS_FRAMES)
        return self._flushed_k

    def _produce_block(self) -> None:
        fs = self.sample_rate_hz
        k_now = math.floor(self.clock.now_s() * fs + _EPS_FRAMES)
        self.next_frame = max(self.next_frame, self._note_flush())
        if isinstance(self.clock, SimClock):
            self.next_frame = max(self.next_frame, k_now)
            n_frames = self.block_frames
        else:
            self.next_frame = max(self.next_frame, k_now - self._max_lag_frames())
            n_frames = min(self.block_frames, self._real_frames(_REAL_BLOCK_WALL_S))
        k0 = self.next_frame
        k = np.arange(k0, k0 + n_frames, dtype=np.int64)
        t_end_s = (k0 + n_frames) / fs
        if not isinstance(self.clock, SimClock) and not self._wait_real_time(t_end_s):
            return
        data, n_garbage, k_first = self._encode_block(k)
        self.next_frame = k0 + n_frames
        written = self._write_all(data, n_garbage, k_first)
        if written is None:
            return
        self.frames_written += written
        if isinstance(self.clock, SimClock):
            self.clock.advance_to(t_end_s)

    def _encode_block(self, k: np.ndarray) -> tuple[bytes, int, int]:
        """Frames for grid indices ``k`` with the armed faults applied.

        Returns (bytes, garbage prefix length, grid index of the first frame written).
        """
        t_s = k / self.sample_rate_hz
        rate_out, temp_c = self.source(t_s)
        force = None if self.specific_force is None else self.specific_force(t_s, temp_c)
        rate_out = np.asarray(rate_out, dtype=np.float64)
        if rate_out.ndim == 2:      # a three-axis IMU source: every axis as it is
            rate = np.array(rate_out, dtype=np.float64, copy=True).reshape(k.size, 3)
        else:                       # a single-axis gyro: its output on the unit-under-test axis
            rate = np.zeros((k.size, 3), dtype=np.float64)
            rate[:, self.axis] = rate_out.reshape(k.shape)
        if self.with_temperature:
            if temp_c is None:
                raise ValueError("simulated gyro: with_temperature=True but the source gave no temperature")
            temp_c = np.broadcast_to(np.asarray(temp_c, dtype=np.float64).reshape(-1, 1), (k.size, 3))
        else:
            temp_c = None

        n_lost = self._take_up_to("lose_frames", k.size)
        n_corrupt = self._take_up_to("corrupt_frames", k.size - n_lost)
        n_saturate = self._take_up_to("saturate", k.size - n_lost - n_corrupt)
        saturated = slice(n_lost + n_corrupt, n_lost + n_corrupt + n_saturate)
        rate[saturated, self.axis] = 2.0 * RAW_FULL_SCALE * self.lsb

        frames = encode_sim_frames(k, rate, temp_c, layout=self.layout, lsb=self.lsb,
                                   latency_us=self.latency_us, sample_rate_hz=self.sample_rate_hz,
                                   accelerometer_range_g=self.accelerometer_range_g, force=force)
        # Flip the middle rate byte: never the identifier, so the span still
        # looks like a frame and must be caught by the CRC.
        frames[n_lost : n_lost + n_corrupt, RATE_OFFSET + 3 * self.axis + 1] ^= 0xFF
        frames = frames[n_lost:]
        self.injected["lose_frames"] += n_lost
        self.injected["corrupt_frames"] += n_corrupt
        self.injected["saturate"] += n_saturate

        garbage = b""
        params = self.faults.take("garbage")
        if params is not None:
            n_bytes = int(params.get("n_bytes", 32))
            garbage = self._rng.integers(0, 256, n_bytes, dtype=np.uint8).tobytes()
            self.injected["garbage_bytes"] += n_bytes
        return garbage + frames.tobytes(), len(garbage), int(k[0]) + n_lost

    def _take_up_to(self, name: str, limit: int) -> int:
        """Consume up to ``limit`` firings of a per-frame fault (no work when not armed)."""
        taken = 0
        while taken < limit and self.faults.is_armed(name) and self.faults.take(name) is not None:
            taken += 1
        return taken

    def _wait_real_time(self, t_s: float) -> bool:
        """Pace on a real clock; False if stopped while waiting."""
        speed = getattr(self.clock, "speed", 1.0)
        while True:
            remaining_s = t_s - self.clock.now_s()
            if remaining_s <= 0:
                return True
            if self._stop.wait(min(remaining_s / speed, _POLL_S)):
                return False

    def _write_all(self, data: bytes, frames_from: int, k_first: int) -> int | None:
        """Blocking write into the master, with ``select`` so that stop() is prompt.

        Returns the number of frames written, None if stopped. Frames sampled
        before the reader's last input flush are never written (see
        :meth:`_note_flush`). On a real clock, frames more than
        :data:`_REAL_MAX_LAG_S` older than the clock are dropped (a real unit
        would have sent them long ago). On a SimClock,
        frames whose time the clock has already passed are stale: while the
        writer waited for the reader, someone else moved time on (the
        orchestrator changed the table rate, settled, and flushed its input),
        so those frames describe conditions that no longer hold and would be
        read as the first samples of the next step. At every frame boundary
        the writer therefore skips the frames older than the clock; a frame
        in progress is always completed, so no garbage is made.
        """
        length = self.layout.length
        view = memoryview(data)
        position = 0
        skipped = 0
        simulated = isinstance(self.clock, SimClock)
        lag_frames = 0 if simulated else self._max_lag_frames()
        while position < len(data):
            if self._stop.is_set():
                return None
            _, writable, _ = select.select([], [self._master_fd], [], _POLL_S)
            if not writable:
                continue
            limit = len(data)
            if position >= frames_from:
                offset = (position - frames_from) % length
                if offset == 0:
                    k_now = math.ceil(self.clock.now_s() * self.sample_rate_hz - _EPS_FRAMES) - lag_frames
                    k_keep = max(k_now, self._note_flush())
                    keep_from = min(frames_from + max(0, k_keep - k_first) * length, len(data))
                    if keep_from > position:
                        skipped += (keep_from - position) // length
                        position = keep_from
                        continue
                else:
                    limit = position + length - offset   # finish this frame, then look again
            try:
                position += os.write(self._master_fd, view[position:limit])
            except BlockingIOError:
                continue
            except OSError as exc:
                if exc.errno == errno.EIO and self._stop.is_set():
                    return None
                raise
        return (len(data) - frames_from) // length - skipped
