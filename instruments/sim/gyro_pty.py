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
* ``SimClock``: the stream follows what the controller asks (the clock
  calls :meth:`SimulatedGyroPort._on_advance` in the controller's thread).
  While the controller reads (``clock.elapse_reading``) every frame of the
  elapsed span is made, in order, and handed to a delivery thread that only
  moves bytes into the pty (blocking while the reader is behind); frames a
  fault loses or corrupts are made up by the frames that follow, as the
  real unit keeps streaming while its reader waits. While the controller
  waits for something else (``clock.sleep``) nobody reads: the frames older
  than the last :data:`_IDLE_TAIL_S` are skipped (a counter gap), what was
  still queued is dropped and the pty's input is flushed, as in a UART
  nobody reads. The tail itself is made when the controller next reads
  (before that read's frames), and not at all if it waits again first (that
  wait's tail replaces it, as the UART's newer frames would) or flushes its
  input first (packet mode tells): a soak polled every 10 s made ~3,000 tails
  in an overnight dry run that no reader ever saw, 10 % of its CPU time. So a
  reader sees the tail only by advancing the clock, as the orchestrator
  always does before it reads. Frames are made in the controller's thread,
  so which frames exist and what they say depends only on its calls, never
  on scheduling.

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

Commands: the unit answers ``C<CR>`` (TS1524 §8.3, p. 59) with its
configuration datagram (stim_configuration.py), ``N<CR>`` with its Part Number
datagram and ``I<CR>`` with its Serial Number datagram (§8.1, §8.2, p. 58;
stim_identity.py; a unit given no serial of the Table 5-15 form does not
answer ``I``), each replacing the next normal-mode datagram(s) it would have sent. The reader's writes arrive on the
packet-mode master as data packets beside the flush statuses. On simulated
time the command is looked for when the controller next advances the clock
(it wrote the command before), and the answer replaces the first datagram(s)
of that read span, so where it falls depends on the controller's calls alone;
on a real clock it replaces the first datagram(s) of the next block. Other
commands (Table 8-1) are not simulated and go unanswered.

Start-up: a unit on a station's supply (``starts_from``, set by the simulated
station) sends its part number, serial number and configuration datagrams
(no bias trim offset: its configuration's byte 21 says so) when it starts,
before its first normal-mode datagram (§7.5.1, p. 47; Table 5-2 Note 1, p. 8).
They are sent back to back just before that datagram, in the start-up delay,
so the normal-mode grid is as without them (the gap between them and the
first normal-mode datagram is not given by the datasheet: unconfirmed).
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
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from gyrocal.instruments.gyro import crc32_mpeg2, field_packing
from gyrocal.instruments.gyro.datagram import (
    DEFAULT_ACCELEROMETER_RANGE_G,
    DEFAULT_LSB,
    RATE_OFFSET,
    RAW_FULL_SCALE,
    layout_for,
    layout_of,
)
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.gyro_frames import (
    SpecificForce,
    SpecificForceSource,
    encode_sim_frames,
)
from gyrocal.instruments.sim.pty_port import PtyWriterPort
from gyrocal.instruments.sim.stim_configuration import (
    SimUnitConfiguration,
    configuration_datagram,
    replaced_datagrams,
)
from gyrocal.instruments.sim.stim_identity import (
    SIM_PART_NUMBER,
    SIM_REVISION,
    carries_serial,
    part_number_datagram,
    serial_number_datagram,
)
from gyrocal.models.clock import RealClock, SimClock
from gyrocal.models.sim_state import decode, encode

FAULTS = ("corrupt_frames", "lose_frames", "garbage", "stall", "saturate")

#: frame times → (rate: (n,) for a single-axis gyro or (n, 3) for an IMU, temperature or None)
GyroSource = Callable[[np.ndarray], tuple[np.ndarray, "np.ndarray | None"]]
#: what a staged source's frames see (table rate, chamber temperature, table angle; per frame)
SourceInputs = tuple[np.ndarray, np.ndarray, np.ndarray]


@runtime_checkable
class StagedGyroSource(Protocol):
    """A source whose physics is read apart from its (costly) gyro model.

    On simulated time the port reads the physics a span's frames see in the
    controller's thread (cheap, and fixed before the controller can command
    anything new) and leaves the model, the noise and the encoding to its own
    thread, beside the reader. A plain :data:`GyroSource` must then be a pure
    function of the frame times.
    """

    def inputs_at(self, t_s: np.ndarray) -> SourceInputs:
        """The physics at the frame times ``t_s``."""

    def emit(self, t_s: np.ndarray, inputs: SourceInputs) -> tuple[np.ndarray, np.ndarray | None]:
        """The gyro's output for frames at ``t_s`` that see ``inputs`` (continues its state)."""

#: simulated clock: most wall time a controller waits for its command to cross the pty
HEAR_TIMEOUT_S = 2.0
_POLL_S = 0.05          # how often blocking waits look at the stop flag
_REAL_BLOCK_WALL_S = 0.01      # real clock: a block spans at most this much wall time
_REAL_MAX_LAG_S = 2.0          # real clock: frames older than this (clock s) behind the clock are dropped
_EPS_FRAMES = 1e-6      # tolerance when converting clock time to a frame number
_IDLE_TAIL_S = 0.1      # simulated clock, nobody reading: the frames of this last span are sent
_WRITE_BYTES = 1 << 16  # simulated clock: bytes handed to the pty per write
#: simulated clock: frames of a read span made per model call (the port's
#: ``span_block_frames``). The model and the encoder cost ~0.2 ms a call besides their
#: per-frame work, so 512-frame calls spent ~60 % of an overnight dry run's gyro
#: simulation on that fixed cost (10 M frames: 1.0 µs a frame at 512, 0.4 µs at 2500,
#: 0.3 µs at 8192, measured). The model and its noise are the same however a record is
#: cut into calls (gyro_sim.py), so the frames are the same bytes; per-block faults
#: (armed between calls) see fewer, larger blocks.
SPAN_BLOCK_FRAMES = 8192


class SimulatedGyroPort(PtyWriterPort):
    """Streams datagrams from ``source`` into a pty; the driver opens :attr:`port_name`."""

    thread_name = "sim-gyro-pty"
    label = "simulated gyro"
    _pty_full = False       # the last write into the pty took less than it was offered

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
        baudrate: int = 921600,
        gyro_output_code: int = 0,
        unit_serial: str | None = None,
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
        #: simulated clock: a read span's frames are made in calls of this many (at least
        #: ``block_frames``); a test that arms faults block by block may set it
        self.span_block_frames = SPAN_BLOCK_FRAMES
        self.latency_us = int(latency_us)
        self._rng = np.random.default_rng(seed)
        self.injected = {
            "corrupt_frames": 0, "lose_frames": 0, "garbage_bytes": 0, "saturate": 0, "stalls": 0,
        }
        self.frames_written = 0         # frames fully handed to the pty
        self.next_frame = 0             # k of the next frame to produce
        self.error: BaseException | None = None   # what ended the writer thread, if anything
        super().__init__()
        # packet mode: the master reads a status byte when the reader flushes its input
        fcntl.ioctl(self._master_fd, termios.TIOCPKT, struct.pack("i", 1))
        self._flushed_k = -(2**62)      # frames before this one were flushed by the reader
        self._out = bytearray()         # simulated clock: bytes made, not yet in the pty
        self._out_lock = threading.Condition()
        self._spans: deque[_Span] = deque()   # simulated clock: read spans not yet made
        self._tail: tuple[int, int] | None = None   # simulated clock: idle tail [k0, k1) not yet made
        self._making = False                  # the stream thread is making a span
        self._bytes_made = 0                  # simulated clock: bytes made (bytes_made())
        self._init_commands(int(baudrate), int(gyro_output_code), unit_serial)

    def _init_commands(self, baudrate: int, gyro_output_code: int, unit_serial: str | None) -> None:
        """What the unit answers C, N and I with (its gyro output code: 0 angular rate, Table
        5-16 byte 5; its serial: the procedure's, when Table 5-15 can carry it), and the
        state of the reader's commands."""
        kind = self.layout.kind
        self.unit = SimUnitConfiguration(self.sample_rate_hz, kind.acceleration, kind.inclination,
                                         kind.temperature, kind.pps, self.crlf, baudrate,
                                         self.accelerometer_range_g, gyro_output_code)
        self.unit_serial = unit_serial if carries_serial(unit_serial) else None
        self.configuration_answers = 0        # C<CR> answered
        self.identity_answers = 0             # N<CR> and I<CR> answered
        self.start_ups = 0                    # times the start-up datagrams were sent
        self._command_bytes = bytearray()     # the reader's writes, up to the next CR
        self._commands_heard = 0              # commands executed (CR received), answered or not
        self._answers_due: list[bytes] = []   # answers to commands received, not sent yet
        self._flush_pending = False           # the reader flushed its input, not yet acted on
        #: when the unit, on the station's supply, starts sending (None: off); None: always on
        self.starts_from: Callable[[], float | None] | None = None

    def _answer(self, command: bytes) -> bytes:
        """The datagram a Normal Mode command asks for (Table 8-1), or b'' (not simulated)."""
        if command == b"C" and self.unit.answers:
            return configuration_datagram(self.unit)
        if command == b"N":
            return part_number_datagram(SIM_PART_NUMBER, SIM_REVISION, self.crlf)
        if command == b"I" and self.unit_serial is not None:
            return serial_number_datagram(self.unit_serial, self.crlf)
        return b""

    def start_up_datagrams(self) -> bytes:
        """What the unit sends when it starts (§7.5.1): part number, serial, configuration."""
        serial = b"" if self.unit_serial is None else serial_number_datagram(self.unit_serial, self.crlf)
        configuration = configuration_datagram(self.unit) if self.unit.answers else b""
        return part_number_datagram(SIM_PART_NUMBER, SIM_REVISION, self.crlf) + serial + configuration

    # ------------------------------------------------------------------ lifecycle

    def _before_start(self) -> None:
        crc32_mpeg2.warm_up()      # the compiled CRC, before the first (timed) exchange
        field_packing.warm_up()    # and the compiled field packing
        if isinstance(self.clock, SimClock):
            self.next_frame = max(self.next_frame, self._frames_before(self.clock.now_s()))
            self.clock.subscribe(self._on_advance)

    def _before_join(self) -> None:
        if isinstance(self.clock, SimClock):
            self.clock.unsubscribe(self._on_advance)
        with self._out_lock:
            self._out_lock.notify_all()

    # ------------------------------------------------------------------ writer

    def _run(self) -> None:
        if isinstance(self.clock, SimClock):
            self._deliver()
            return
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

    # ------------------------------------------------------------------ simulated clock

    def _frames_before(self, t_s: float) -> int:
        """Number of grid frames k with t_k = k / fs earlier than ``t_s``."""
        return math.ceil(t_s * self.sample_rate_hz - _EPS_FRAMES)

    def _on_advance(self, from_s: float, to_s: float, reading: bool) -> None:
        """The controller moved simulated time to ``to_s``: the frames of the span.

        Runs in the controller's thread, before its call returns. Which frames
        exist, and the physics each one sees, are fixed here, from its calls
        alone; the model and the encoding of a read span run on the stream
        thread in order (:meth:`_make_span`), so two runs with one seed give
        the same bytes however the threads are scheduled.
        """
        if self._stop.is_set():
            return
        try:
            self._wait_made()
            self._poll_master()
            if reading:
                if not self._honour_reader_flush():
                    self._send_tail()
                self._queue_read_span(to_s - from_s)
            else:
                # nobody reads: an answer the unit sent now is lost with the UART's other frames
                self._answers_due.clear()
                self._hold_idle_tail(self._frames_before(to_s))
        except Exception as exc:  # noqa: BLE001 - reported through .error; the driver sees silence
            self.error = exc
            self._stop.set()

    def _queue_read_span(self, span_s: float) -> None:
        """Every frame of ``span_s`` (counted from the span, so n / fs seconds make n frames)."""
        span = int(round(span_s * self.sample_rate_hz))
        if span <= 0:
            return
        k = np.arange(self.next_frame, self.next_frame + span, dtype=np.int64)
        inputs = (self.source.inputs_at(k / self.sample_rate_hz)
                  if isinstance(self.source, StagedGyroSource) else None)
        answer = self._take_answer()
        with self._out_lock:
            self._spans.append(_Span(k, inputs, answer))
            self._making = True
            self._out_lock.notify_all()

    def _wait_made(self) -> None:
        """Block until every queued span is made (its frame numbers are then final)."""
        with self._out_lock:
            while (self._spans or self._making) and not self._stop.is_set():
                self._out_lock.wait(_POLL_S)

    def _make_span(self, span: _Span) -> None:
        """Frames of a read span, then as many more as faults made unreadable.

        Make-up frames come in whole blocks (a surplus stays with the reader) and
        see the conditions of the span's last frame (the controller may command
        new ones as soon as its read is complete); a stream that loses nearly
        everything is not made up past twice the span: the reader then times
        out, as it would on the rig.
        """
        wanted, made, total = span.k.size, 0, span.k.size
        while wanted > 0 and made < 2 * total + 2 * self.block_frames and not self._stop.is_set():
            k0 = self.next_frame
            if made < total:
                rows = slice(made, made + min(max(self.block_frames, self.span_block_frames), wanted))
                inputs = None if span.inputs is None else tuple(x[rows] for x in span.inputs)
                size = rows.stop - rows.start
            else:
                size = self.block_frames
                inputs = None if span.inputs is None else tuple(
                    np.repeat(x[-1:], size, axis=0) for x in span.inputs)
            k = np.arange(k0, k0 + size, dtype=np.int64)
            before = self.injected["lose_frames"] + self.injected["corrupt_frames"]
            data, n_garbage, _ = self._encode_block(k, inputs)
            if made == 0 and span.answer:
                data, _, _ = self._splice_answer(data, n_garbage, k0, span.answer)
            self._bytes_made += len(data)
            self.next_frame = k0 + size
            made += size
            wanted -= size - (self.injected["lose_frames"] + self.injected["corrupt_frames"] - before)
            with self._out_lock:
                self._out += data
            if not self.faults.is_armed("stall"):
                self._write_some()      # the reader starts on this block while the next is made

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """Draw the injected garbage from ``seed`` from now on (a dry run's attempt)."""
        self._wait_made()
        self._rng = np.random.default_rng(seed)

    def bytes_made(self) -> int:
        """Simulated clock: bytes made so far (read spans and idle tails), once every queued
        span is made. A deterministic function of the controller's calls, unlike what the
        pty holds at a wall-clock instant (the kernel moves written bytes to the reader's
        side in its own time), so a first-frame poll can tell whether frames came in its
        interval without racing the stream thread (``orchestrator/turn_on.py``)."""
        self._wait_made()
        return self._bytes_made

    def sim_state(self) -> dict:
        """Where the frame grid is and the garbage stream (``models/sim_state.py``), once
        every queued span is made."""
        self._wait_made()
        return {"next_frame": int(self.next_frame), "rng": encode(self._rng)}

    def restore_sim_state(self, state: dict) -> None:
        """Continue the grid at the snapshot's frame; what this session made and nobody
        read is dropped, as a reader's flush would drop it."""
        self._wait_made()
        with self._out_lock:
            self._out.clear()
            termios.tcflush(self._slave_fd, termios.TCIFLUSH)
        self.next_frame = int(state["next_frame"])
        self._tail = None       # a held idle tail: in the queue a reader's flush drops
        self._rng = decode(state["rng"], self._rng)

    def _hold_idle_tail(self, k_end: int) -> None:
        """Nobody reads: only the last frames are in the UART; older ones are gone.

        What was queued is dropped and the pty's input flushed now; the tail's frames
        are made by :meth:`_send_tail` if the controller reads next.
        """
        tail = max(1, int(round(_IDLE_TAIL_S * self.sample_rate_hz)))
        k_start = max(self.next_frame, k_end - tail)
        self.next_frame = max(self.next_frame, k_end)
        with self._out_lock:
            self._out.clear()
            termios.tcflush(self._slave_fd, termios.TCIFLUSH)
        self._reader_flushed()          # our own flush's status: a later one is the reader's
        self._tail = (k_start, k_end) if k_end > k_start else None

    def _honour_reader_flush(self) -> bool:
        """If the reader flushed its input since the last look, drop everything made before.

        Frames made and not yet read (a fault's make-up surplus, the held idle tail)
        were sampled before the flush: on a serial port they were in the flushed
        queue or in flight with it. Here they go, under the writer's lock and in the
        controller's thread before any new frame is made, whatever the writer had
        already pushed into the pty since the flush included. So nothing made before
        a reader's flush ever reaches it, and a driver's wait for in-flight bytes
        (``Clock.transport_wait``) has nothing to wait for on simulated time.
        Returns whether the reader had flushed.
        """
        if not self._reader_flushed():
            return False
        with self._out_lock:
            self._out.clear()
            termios.tcflush(self._slave_fd, termios.TCIFLUSH)
        self._reader_flushed()          # our own flush's status: a later one is the reader's
        self._tail = None
        return True

    def _send_tail(self) -> None:
        """The held idle tail into the pty, before a read's frames (the caller has
        checked that the reader did not flush its input since: the tail would have been
        in the flushed queue)."""
        if self._tail is None:
            return
        k_start, k_end = self._tail
        self._tail = None
        data, _, _ = self._encode_block(np.arange(k_start, k_end, dtype=np.int64))
        self._bytes_made += len(data)
        # Written here, under the lock, before the read span is queued; what does not
        # fit is lost, as in a full UART.
        with self._out_lock, contextlib.suppress(BlockingIOError):
            os.write(self._master_fd, data)

    def _reader_flushed(self) -> bool:
        """Whether the reader flushed its input since the last look (packet-mode status)."""
        self._poll_master()
        flushed, self._flush_pending = self._flush_pending, False
        return flushed

    def _poll_master(self) -> None:
        """Read what the reader did: input flushes (status packets) and its writes (data packets)."""
        while select.select([self._master_fd], [], [], 0)[0]:
            try:
                packet = os.read(self._master_fd, 4096)
            except BlockingIOError:
                break
            if not packet:
                break
            if packet[0] == termios.TIOCPKT_DATA:
                self._command_bytes += packet[1:]
            elif packet[0] & termios.TIOCPKT_FLUSHREAD:
                self._flush_pending = True
        while b"\r" in self._command_bytes:        # CR executes a command (Table 8-2)
            command, _, rest = bytes(self._command_bytes).partition(b"\r")
            self._command_bytes = bytearray(rest)
            self._commands_heard += 1
            answer = self._answer(command)
            if answer:
                self._answers_due.append(answer)

    def hear_command(self, timeout_s: float = HEAR_TIMEOUT_S) -> bool:
        """Simulated time: wait until a command the reader has written has crossed the pty.

        A write on the slave reaches the master through the kernel's flip-buffer work,
        asynchronously: looked for only when the controller next advances the clock
        (``_poll_master``), a command could be missed under load and answered a span
        later or never — the dry run would then differ from run to run. The
        controller calls this after writing a command and before it lets the
        command's time pass, so the command is always heard at that moment. Wall
        time, bounded (False: nothing arrived); called on the controller's thread,
        where the clock's advances run too.
        """
        heard = self._commands_heard
        deadline = time.monotonic() + timeout_s
        while True:
            self._poll_master()
            if self._commands_heard > heard:
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            select.select([self._master_fd], [], [], remaining)

    def _take_answer(self) -> bytes:
        """The datagrams commands are waiting for, in the order asked, else b''."""
        for answer in self._answers_due:
            if answer[0] in (0xBC, 0xBD):
                self.configuration_answers += 1
            else:
                self.identity_answers += 1
        answers, self._answers_due = b"".join(self._answers_due), []
        return answers

    def _splice_answer(self, data: bytes, n_garbage: int, k_first: int, answer: bytes
                       ) -> tuple[bytes, int, int]:
        """Put the answer in place of the block's first datagram(s) (TS1524 §8.3).

        Returns (bytes, length of what precedes the frames, grid index of the first frame).
        """
        length = self.layout.length
        frames = len(data) - n_garbage
        if frames < length:             # a unit switched off sends nothing, no answer either
            return data, n_garbage, k_first
        replaced = min(replaced_datagrams(len(answer), self.unit.bit_rate, self.sample_rate_hz),
                       frames // length)
        data = data[:n_garbage] + answer + data[n_garbage + replaced * length:]
        return data, n_garbage + len(answer), k_first + replaced

    def _write_some(self) -> int:
        """One non-blocking write of what is made; returns the bytes written.

        Written from a view: the pty takes ~3 KiB a write, and a slice of the bytearray
        copied 64 KiB for each (an IMU dry run's ~133,000 writes: ~8 GB of copying). The
        views are released before the written bytes are cut off the front.
        """
        with self._out_lock:
            if not self._out:
                return 0
            try:
                with memoryview(self._out) as out, out[:_WRITE_BYTES] as head:
                    written = os.write(self._master_fd, head)
                    self._pty_full = written < len(head)
            except BlockingIOError:
                return 0
            del self._out[:written]
            self.frames_written += written // self.layout.length
            return written

    def _deliver(self) -> None:
        """The stream thread: make the queued read spans, move the bytes into the pty."""
        try:
            while not self._stop.is_set():
                with self._out_lock:
                    if not self._spans and not self._out:
                        self._out_lock.wait(_POLL_S)
                        continue
                    span = self._spans.popleft() if self._spans else None
                if span is not None:
                    self._make_span(span)
                    with self._out_lock:
                        self._making = bool(self._spans)
                        self._out_lock.notify_all()
                    continue
                if self._stalled():
                    continue
                if not self._write_some() or self._pty_full:
                    # nothing taken, or less than offered: full until the reader drains it (a
                    # write tried at once would only fail, ~130,000 times in an IMU dry run)
                    select.select([], [self._master_fd], [], _POLL_S)
        except OSError as exc:
            if not self._stop.is_set():
                self.error = exc
        except Exception as exc:  # noqa: BLE001 - reported through .error; the driver sees silence
            self.error = exc
        finally:
            with self._out_lock:
                self._making = False
                self._out_lock.notify_all()

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
        if self._reader_flushed():
            self._flushed_k = math.ceil(self.clock.now_s() * self.sample_rate_hz - _EPS_FRAMES)
        return self._flushed_k

    def _produce_block(self) -> None:
        fs = self.sample_rate_hz
        k_now = math.floor(self.clock.now_s() * fs + _EPS_FRAMES)
        self.next_frame = max(self.next_frame, self._note_flush())
        self.next_frame = max(self.next_frame, k_now - self._max_lag_frames())
        n_frames = min(self.block_frames, self._real_frames(_REAL_BLOCK_WALL_S))
        k0 = self.next_frame
        k = np.arange(k0, k0 + n_frames, dtype=np.int64)
        t_end_s = (k0 + n_frames) / fs
        if not self._wait_real_time(t_end_s):
            return
        data, n_garbage, k_first = self._encode_block(k)
        answer = self._take_answer()
        if answer:
            data, n_garbage, k_first = self._splice_answer(data, n_garbage, k_first, answer)
        self.next_frame = k0 + n_frames
        written = self._write_all(data, n_garbage, k_first)
        if written is None:
            return
        self.frames_written += written

    def _encode_block(self, k: np.ndarray, inputs: SourceInputs | None = None
                      ) -> tuple[bytes, int, int]:
        """Frames for grid indices ``k`` with the armed faults applied.

        ``inputs``: the physics a staged source's frames see, read beforehand.
        Returns (bytes, garbage prefix length, grid index of the first frame written).
        """
        t_s = k / self.sample_rate_hz
        grid = (int(k[0]), int(k[-1]))
        rate_out, temp_c = (self.source(t_s) if inputs is None
                            else self.source.emit(t_s, inputs))
        force = None if self.specific_force is None else self.specific_force(t_s, temp_c)
        rate_out = np.asarray(rate_out, dtype=np.float64)
        if rate_out.ndim == 2:      # a three-axis IMU source: every axis as it is
            rate = np.array(rate_out, dtype=np.float64, copy=True).reshape(k.size, 3)
        else:                       # a single-axis gyro: its output on the unit-under-test axis
            rate = np.zeros((k.size, 3), dtype=np.float64)
            rate[:, self.axis] = rate_out.reshape(k.shape)
        if rate_out.ndim == 1 and np.isnan(rate_out).any():
            # an unpowered unit sends nothing (station_sim.UnitPower): keep the frames it sends
            sent = ~np.isnan(rate_out.reshape(k.shape))
            k, rate = k[sent], rate[sent]
            if temp_c is not None and np.ndim(temp_c) > 0:
                temp_c = np.asarray(temp_c).reshape(-1)[sent]
            force = None if force is None else SpecificForce(force.acc_g[sent], force.incl_g[sent])
            if k.size == 0:
                return b"", 0, int(t_s[-1] * self.sample_rate_hz) + 1
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
        garbage += self._start_up_before(grid, k[n_lost:])
        return garbage + frames.tobytes(), len(garbage), int(k[0]) + n_lost

    def _start_up_before(self, grid: tuple[int, int], sent: np.ndarray) -> bytes:
        """The start-up datagrams, when this block holds the unit's first normal-mode frame
        since it was switched on (grid: the block's first and last frame numbers; sent: the
        numbers of the frames it sends). Ahead of the frames, as a prefix, so the writers
        keep their frame alignment."""
        starts = None if self.starts_from is None else self.starts_from()
        if starts is None:
            return b""
        k_start = self._frames_before(starts)
        if not grid[0] <= k_start <= grid[1] or (sent.size and int(sent[0]) < k_start):
            return b""
        self.start_ups += 1
        return self.start_up_datagrams()

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

        Returns the number of frames written, None if stopped (real clock
        only). Frames sampled before the reader's last input flush are never
        written (see :meth:`_note_flush`), and frames more than
        :data:`_REAL_MAX_LAG_S` older than the clock are dropped (a real unit
        would have sent them long ago); a frame in progress is always
        completed, so no garbage is made.
        """
        length = self.layout.length
        view = memoryview(data)
        position = 0
        skipped = 0
        lag_frames = self._max_lag_frames()
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


@dataclass(frozen=True)
class _Span:
    """A read span queued for the stream thread: its frame numbers and, for a staged
    source, the physics those frames see."""

    k: np.ndarray
    inputs: SourceInputs | None
    answer: bytes = b""         # a configuration datagram replacing the span's first datagram(s)
