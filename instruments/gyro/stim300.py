"""Driver for a STIM300-style gyro streaming datagrams over a serial line.

The unit streams continuously at its configured rate. The driver sends three
things, at connect, each through one request path (:meth:`Stim300Gyro._request`):
``N<CR>`` and ``I<CR>``, which ask the unit for its part and serial numbers
(:meth:`Stim300Gyro.ask_identity`, identity_query.py), and ``C<CR>``, which
asks for its configuration datagram (:meth:`Stim300Gyro.confirm_configuration`,
configuration_query.py). After a flush (and at open) it watches for the special
datagrams a unit sends when it starts (TS1524 §7.5.1) until the first
normal-mode datagram: they are cut from the stream, decoded and kept for the
journal (:meth:`Stim300Gyro.take_start_up`), never counted as garbage.
It reads large chunks (whatever is waiting, at least what the
request still needs) and decodes them vectorised, so a 2 kHz stream costs a
handful of system calls and numpy calls per block, not a Python loop per
frame. Samples decoded beyond what was asked are kept for the next call,
so no good sample is ever dropped between blocks.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import serial

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentProtocolError,
    InstrumentTimeout,
)
from gyrocal.instruments.gyro.configuration import UnitConfiguration
from gyrocal.instruments.gyro.configuration_query import (
    COMMAND,
    WAIT_FRAMES,
    ConfigurationAnswer,
    Declared,
    mismatches,
)
from gyrocal.instruments.gyro.datagram import (
    DEFAULT_ACCELEROMETER_RANGE_G,
    DEFAULT_LSB,
    DecodedFrames,
    FrameDecoder,
    axis_index,
    concat_decoded,
    flagged,
)
from gyrocal.instruments.gyro.datagram_types import counter_step
from gyrocal.instruments.gyro.identity_query import (
    PART_NUMBER_COMMAND,
    SERIAL_NUMBER_COMMAND,
    IdentityAnswer,
    StartUpRecord,
)
from gyrocal.instruments.gyro.special_datagrams import (
    CONFIGURATION,
    PART_NUMBER,
    SERIAL_NUMBER,
    Found,
    PartNumber,
    SerialNumber,
    SpecialKind,
    cut_specials,
    locate_special,
    replaced_frames,
)
from gyrocal.instruments.gyro.survey import StreamSurvey, survey_stream
from gyrocal.instruments.interfaces import GyroBlock, Identity

_POLL_S = 0.05                  # longest single blocking read, so deadlines are honoured
_MAX_READ_BYTES = 4 << 20       # cap per read() so one call cannot hoard memory
_FLUSH_SETTLE_S = 0.02          # > a USB-serial adapter's latency timer (FTDI default 16 ms)
_SURVEY_MIN_FRAMES = 4          # datagrams that must check before the stream's type is judged
_SURVEY_MAX_BYTES = 1 << 16     # no datagram of any type in this much: the line carries none
_START_UP_SCAN_BYTES = 4096     # start-up datagrams are looked for this much at a time (< 120 bytes)


@dataclass(frozen=True)
class _Answer:
    """A command's answer as cut from the stream (:meth:`Stim300Gyro._request`)."""

    found: Found
    replaced_frames: int | None     # the normal-mode datagrams it took the place of
    rest: bytes                     # what was read after it


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
        datagram: int | None = None,
        accelerometer_range_g: int = DEFAULT_ACCELEROMETER_RANGE_G,
        transport_wait: Callable[[float], None] = time.sleep,
    ) -> None:
        self.port = port
        #: how the flush waits for in-flight bytes: wall time on a real port; the run's
        #: clock decides (``Clock.transport_wait``: at once on simulated time)
        self._transport_wait = transport_wait
        self.name = name
        self.baudrate = int(baudrate)
        self.sample_rate_hz = float(sample_rate_hz)
        self.with_temperature = bool(with_temperature)
        self.lsb = float(lsb)
        self.timeout_s = float(timeout_s)
        self.axis = axis
        self._axis = axis_index(axis)
        self.crlf = bool(crlf)
        self.accelerometer_range_g = int(accelerometer_range_g)
        self._decoder = FrameDecoder(with_temperature=with_temperature, lsb=lsb, crlf=self.crlf,
                                     datagram=datagram, counter_step=counter_step(self.sample_rate_hz),
                                     accelerometer_range_g=self.accelerometer_range_g)
        self.layout = self._decoder.layout
        self.with_temperature = self.layout.with_temperature
        self._survey_bytes = bytearray()     # the first bytes, until the stream's type is confirmed
        self.survey: StreamSurvey | None = None
        self._frame_length = self._decoder.layout.length
        #: what the unit said when asked for its configuration (None: not asked yet)
        self.configuration: ConfigurationAnswer | None = None
        #: what the unit said when asked N and I (None: not asked yet)
        self.unit_identity: IdentityAnswer | None = None
        self._start_up: list[Found] = []     # start-up datagrams cut from the stream, not yet taken
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
                f"STIM300 datagram {layout.kind.label()} ({layout.length}-byte frames), "
                f"{self.sample_rate_hz:g} Hz (counter step {self._decoder.counter_step}), "
                f"lsb={self.lsb:g}"
                f"{f', accelerometers ±{self.accelerometer_range_g} g' if layout.kind.acceleration else ''}, "
                f"{self.baudrate} baud, "
                f"unit under test: {self.axis} axis{', CR LF' if self.crlf else ''}"
                f"{'' if self.unit_identity is None else '; ' + self.unit_identity.describe()}"
                f"{'' if self.configuration is None else '; ' + self.configuration.describe()}"
            ),
        )

    def flush(self) -> None:
        """Drop buffered bytes, the decoder's partial frame and any surplus samples.

        Bytes already in flight when the host buffer is flushed — in a
        USB-serial adapter's FIFO (released on its latency timer, 16 ms on
        FTDI parts) or in the kernel's tty flip buffers — arrive just after
        the flush and would be read as the first samples of the next step,
        though they describe the conditions before it. So the input is
        flushed, left for :data:`_FLUSH_SETTLE_S`, and flushed again. The wait is
        the transport's, not the physics': ``transport_wait`` (the run's clock) makes
        it in wall time on a real port and skips it on simulated time, where a
        simulated gyro drops what it made before the flush itself.
        """
        try:
            self._serial.reset_input_buffer()
            self._transport_wait(_FLUSH_SETTLE_S)
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

    def detect(self, timeout_s: float | None = None) -> StreamSurvey:
        """What the unit sends (datagram type, counter step, rate), checked against the declaration.

        Reads until enough datagrams have checked (the bytes are decoded as
        samples too, kept for the next :meth:`read_samples`); a mismatch
        raises the same fault as the first read would. For a station check.
        """
        timeout_s = self.timeout_s if timeout_s is None else float(timeout_s)
        deadline = time.monotonic() + timeout_s
        while self.survey is None:
            if time.monotonic() >= deadline:
                raise InstrumentTimeout(self.name, "datagram check",
                                        f"not enough datagrams to tell the type within {timeout_s:g} s "
                                        f"({len(self._survey_bytes)} bytes) on {self.port}")
            self._read_chunk(_SURVEY_MIN_FRAMES, "datagram check")
        return self.survey

    def ask_identity(self, timeout_s: float | None = None,
                     let_pass: Callable[[float], None] | None = None) -> IdentityAnswer:
        """Ask the unit its part number (``N<CR>``) and serial (``I<CR>``), TS1524 §8.1–8.2.

        Each through :meth:`_request` (bounded wait, answer cut from the stream);
        an unanswered question is no fault: the answer says "not confirmed". Not
        asked when the unit left ``C<CR>`` unanswered on this line: it is one-way
        (a replay), and each wait would be as long and as silent.
        """
        if self.configuration is not None and self.configuration.configuration is None:
            self.unit_identity = IdentityAnswer(None, None, asked=False)
            return self.unit_identity
        part = self._request(PART_NUMBER_COMMAND, PART_NUMBER, timeout_s, let_pass)
        self._continue_after(part)
        serial = self._request(SERIAL_NUMBER_COMMAND, SERIAL_NUMBER, timeout_s, let_pass)
        self._continue_after(serial)
        self.unit_identity = IdentityAnswer(
            None if part is None or not isinstance(part.found.value, PartNumber) else part.found.value,
            None if serial is None or not isinstance(serial.found.value, SerialNumber)
            else serial.found.value)
        return self.unit_identity

    def confirm_configuration(self, timeout_s: float | None = None,
                              let_pass: Callable[[float], None] | None = None) -> ConfigurationAnswer:
        """Ask the unit for its configuration (``C<CR>``, TS1524 §8.3) and check it.

        Through :meth:`_request`; a contradiction with the station raises the
        fault naming both. Not answered: the answer says the configuration is
        not confirmed (not a fault).
        """
        answer = self._request(COMMAND, CONFIGURATION, timeout_s, let_pass)
        if answer is None or not isinstance(answer.found.value, UnitConfiguration):
            self.configuration = ConfigurationAnswer(None)
            return self.configuration
        config = answer.found.value
        problems = mismatches(config, Declared(self.sample_rate_hz, self.layout, self._axis,
                                               self.accelerometer_range_g))
        self.configuration = ConfigurationAnswer(config, answer.replaced_frames, tuple(problems))
        if problems:       # before the stream after it is judged: the unit's word names it first
            raise InstrumentProtocolError(self.name, "configuration check", "; ".join(problems))
        self._continue_after(answer)
        return self.configuration

    def take_start_up(self) -> StartUpRecord | None:
        """The start-up datagrams cut from the stream since the last call (None: none came)."""
        if not self._start_up:
            return None
        found, self._start_up = tuple(self._start_up), []
        return StartUpRecord(found)

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
        self._watching = True               # until the first normal-mode datagram (§7.5.1)
        self._held_start_up = bytearray()

    def _read_chunk(self, samples_missing: int, command: str) -> None:
        wanted = samples_missing * self._frame_length - self._decoder.pending_bytes
        chunk = self._read_bytes(wanted, command)
        if chunk:
            self._ingest(chunk)

    def _read_bytes(self, wanted: int, command: str) -> bytes:
        try:
            size = min(max(self._serial.in_waiting, wanted, 1), _MAX_READ_BYTES)
            return self._serial.read(size)
        except (serial.SerialException, OSError) as exc:
            raise InstrumentConnectionError(self.name, command, f"read failed on {self.port}: {exc}") from exc

    def _write(self, data: bytes, command: str) -> None:
        try:
            self._serial.write(data)
            self._serial.flush()
        except (serial.SerialException, OSError) as exc:
            raise InstrumentConnectionError(self.name, command, f"write failed on {self.port}: {exc}") from exc

    def _request(self, command: bytes, kind: SpecialKind, timeout_s: float | None,
                 let_pass: Callable[[float], None] | None) -> _Answer | None:
        """Send a Normal Mode command and cut its answer from the stream (Table 8-1).

        The input is flushed, the command written, and the stream read until a
        datagram of ``kind`` whose CRC checks arrives, for at most ``timeout_s``
        and :data:`WAIT_FRAMES` normal-mode datagrams' worth of bytes.
        ``let_pass(span_s)`` is called once after the command: a simulated clock
        lets the stream's time pass there. Found: returns it, how many
        normal-mode datagrams it replaced and the bytes after it, which
        :meth:`_continue_after` decodes once the caller has judged the answer
        (what came before it is dropped, so the datagram(s) it replaced are
        neither lost frames nor garbage). Not found: everything read is decoded
        as the stream it is; returns None.
        """
        timeout_s = self.timeout_s if timeout_s is None else float(timeout_s)
        what = f"{kind.name} request"
        self.flush()
        self._write(command, what)
        if let_pass is not None:
            let_pass(WAIT_FRAMES / self.sample_rate_hz)
        held = self._read_for(kind, timeout_s, what)
        found = locate_special(held, (kind,))
        if found is None:
            self._ingest(bytes(held))
            return None
        return _Answer(found, self._replaced_frames(held, found.start, found.end),
                       bytes(held[found.end:]))

    def _continue_after(self, answer: _Answer | None) -> None:
        """The stream starts afresh right after an answer (as after a flush)."""
        if answer is None:
            return
        self._decoder.reset()
        self._reset_stream_state()
        self._ingest(answer.rest)

    def _read_for(self, kind: SpecialKind, timeout_s: float, what: str) -> bytearray:
        """The bytes after a command, until its answer checks or the bound."""
        held = bytearray()
        limit = WAIT_FRAMES * self._frame_length
        deadline = time.monotonic() + timeout_s
        while len(held) < limit and time.monotonic() < deadline:
            held += self._read_bytes(limit - len(held), what)
            if locate_special(held, (kind,)) is not None:
                break
        return held

    def _replaced_frames(self, held: bytearray, start: int, end: int) -> int | None:
        """Normal-mode datagrams the answer replaced: the counter gap across it (§7.5.2.2.18)."""
        before, after = self._counters(held[:start]), self._counters(held[end:])
        step = self._decoder.counter_step
        if not (before.size and after.size and step):
            return None
        return replaced_frames(int(before[-1]), int(after[0]), step)

    def _counters(self, data: bytes | bytearray) -> np.ndarray:
        """The counters of the declared type's CRC-valid datagrams in ``data``."""
        layout = self.layout
        return FrameDecoder(datagram=layout.identifier, crlf=layout.crlf).feed(bytes(data)).counter

    def _ingest(self, chunk: bytes) -> None:
        """Decode bytes read from the line (checking the stream's type first, once).

        Until the first normal-mode datagram after a flush, start-up datagrams
        are cut out first (:meth:`_cut_start_up`).
        """
        if self._watching:
            chunk = self._cut_start_up(chunk)
        if not chunk:
            return
        if self.survey is None:
            self._check_stream(chunk)
        decoded = self._decoder.feed(chunk)
        self._pending_crc_errors += decoded.crc_errors
        self._pending_garbage_bytes += decoded.garbage_bytes
        if len(decoded):
            self._surplus.append(decoded)
            self._surplus_count += len(decoded)
            if self._watching:      # normal mode: the start-up is over; what was held is stream
                self._watching = False
                self._ingest(bytes(self._held_start_up))
                self._held_start_up = bytearray()

    def _cut_start_up(self, chunk: bytes) -> bytes:
        """``chunk`` without the special datagrams a unit sends at start-up (§7.5.1), kept for
        :meth:`take_start_up`.

        Looked for :data:`_START_UP_SCAN_BYTES` at a time, and only until a normal-mode
        datagram shows (they precede it, so none can follow): a long read after a flush
        is scanned in its first few kilobytes, not throughout. Bytes that may begin one
        not yet complete are held back for the next chunk.
        """
        data = bytes(self._held_start_up) + chunk
        self._held_start_up = bytearray()
        out = bytearray()
        while data:
            kept, found, partial = cut_specials(data[:_START_UP_SCAN_BYTES])
            data = data[_START_UP_SCAN_BYTES:]
            self._start_up += found
            if self._counters(kept).size:
                return bytes(out + kept) + data
            out += kept[:partial]
            if not data:
                self._held_start_up = bytearray(kept[partial:])
            else:
                data = kept[partial:] + data      # look again with what follows
        return bytes(out)

    def _check_stream(self, chunk: bytes) -> None:
        """Compare the datagram type and counter step the unit sends with the declared ones.

        A wrong declaration would decode as line corruption (no frame, every
        byte garbage) or as lost frames on every step; either is a fault
        that says what the unit sends and what the station declares.
        """
        self._survey_bytes += chunk
        found = survey_stream(self._survey_bytes)
        if found.frames_valid < _SURVEY_MIN_FRAMES:
            if len(self._survey_bytes) >= _SURVEY_MAX_BYTES:
                raise InstrumentProtocolError(
                    self.name, "datagram check",
                    f"no datagram of any STIM300 normal-mode type (TS1524 Table 5-21) in the first "
                    f"{len(self._survey_bytes)} bytes on {self.port}; check the baud rate "
                    f"({self.baudrate}) and that the unit is in normal mode")
            return
        self._survey_bytes = bytearray()
        self.survey = found
        declared = self.layout
        if found.layout != declared:
            crlf = " with CR LF" if declared.crlf else ""
            raise InstrumentProtocolError(
                self.name, "datagram check",
                f"the unit sends {found.describe()}; the station declares "
                f"{declared.kind.label()}{crlf}")
        expected_step = self._decoder.counter_step
        if found.counter_step is not None and found.counter_step != expected_step:
            raise InstrumentProtocolError(
                self.name, "datagram check",
                f"the unit's counter steps {found.counter_step} per datagram, i.e. "
                f"{found.sample_rate_hz:g} Hz (TS1524 §7.5.2.2.18: it counts 2000 Hz internal "
                f"samples); the station declares {self.sample_rate_hz:g} Hz (step {expected_step})")

    def _take(self, n: int) -> GyroBlock:
        joined = concat_decoded(self._surplus, self.layout)
        if len(joined) > n:
            self._surplus, self._surplus_count = [joined.sliced(slice(n, None))], len(joined) - n
        else:
            self._surplus, self._surplus_count = [], 0
        taken = joined.sliced(slice(0, n))
        index = taken.index
        lost = 0
        if n:
            lost = int(index[-1] - self._last_index_returned) - n
            self._last_index_returned = int(index[-1])
        extra: dict = {"latency_us": taken.latency_us}
        if taken.temp_c is not None and taken.temp_status is not None:
            extra["temperature_xyz_c"] = taken.temp_c
            extra["temperature_status"] = taken.temp_status
        block = GyroBlock(
            rate=taken.rate[:, self._axis],
            counter=taken.counter,
            index=index,
            status=taken.status,
            temperature_c=None if taken.temp_c is None else taken.temp_c[:, self._axis],
            crc_errors=self._pending_crc_errors,
            lost_frames=lost,
            garbage_bytes=self._pending_garbage_bytes,
            extra=extra,
            rate_xyz=taken.rate,
            flagged=flagged(taken.status, self._axis),
            channels=taken.channels,
        )
        self._pending_crc_errors = 0
        self._pending_garbage_bytes = 0
        return block


