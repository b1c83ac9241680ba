"""A recorded gyro capture served on a pseudo-terminal, byte for byte, at its own rate.

So the drivers are regression-tested on a real unit's bytes, through the
same serial path (pyserial, termios, partial reads) as the simulated gyro
(gyro_pty.py). The rate is the capture's: its datagram type and counter
step are read from the bytes (survey.py, TS1524 §7.5.2.2.18), and bytes are
released in proportion to the clock (``speed`` times real time on a scaled
clock). At the end the capture starts again from its first byte when
``loop`` is set; the counter then jumps, which a reader sees as it would
on a real line (a counter gap), never hidden. Like a real unit, the replay
does not wait for a reader more than half a second behind (the pty full): those bytes are
dropped (the reader sees garbage and a gap), never released late as if current.
"""

from __future__ import annotations

import errno
import os
import select

from gyrocal.instruments.gyro.datagram import FrameDecoder
from gyrocal.instruments.gyro.survey import StreamSurvey, survey_stream
from gyrocal.instruments.sim.pty_port import PtyWriterPort
from gyrocal.models.clock import RealClock

_POLL_S = 0.01           # how often the writer releases the bytes the clock has reached
_MAX_WRITE = 1 << 16
_MAX_LAG_S = 0.5         # a reader this far behind lost the bytes in between, as on a real UART


class ReplayGyroPort(PtyWriterPort):
    """Writes ``data`` into a pty at the capture's rate; the driver opens :attr:`port_name`."""

    thread_name = "replay-gyro-pty"
    label = "replayed gyro"

    def __init__(self, data: bytes, clock: RealClock, loop: bool = True, source: str = "capture") -> None:
        survey = survey_stream(data[: 1 << 18])
        if survey.layout is None or survey.counter_step is None:
            raise ValueError(f"{source}: no STIM300 normal-mode datagram with a valid CRC to replay")
        decoder = FrameDecoder(datagram=survey.layout.identifier, crlf=survey.layout.crlf,
                               counter_step=survey.counter_step)
        decoded = decoder.feed(data)
        datagrams = len(decoded) + decoded.lost_frames
        self.survey: StreamSurvey = survey
        self.data = bytes(data)
        self.clock = clock
        self.loop = bool(loop)
        self.sample_rate_hz = float(survey.sample_rate_hz or 0.0)
        self.duration_s = datagrams / self.sample_rate_hz
        self.bytes_per_s = len(self.data) / self.duration_s
        self.bytes_written = 0        # over all passes (dropped bytes included)
        self.bytes_dropped = 0        # skipped while nobody read (the reader sees a gap)
        self.error: BaseException | None = None
        self._reader_behind = False   # the pty was full at the last write: nobody is reading
        super().__init__()

    @property
    def passes(self) -> int:
        """Whole passes over the capture completed."""
        return self.bytes_written // len(self.data)

    @property
    def address(self) -> str:
        """Where the driver opens it (the simulated station's name for every server's address)."""
        return self.port_name

    def _run(self) -> None:
        t0_s = self.clock.now_s()
        total = len(self.data)
        try:
            while not self._stop.is_set():
                due = int((self.clock.now_s() - t0_s) * self.bytes_per_s)
                if not self.loop:
                    due = min(due, total)
                if due <= self.bytes_written:
                    if not self.loop and self.bytes_written >= total:
                        return
                    self._stop.wait(_POLL_S)
                    continue
                lag = due - self.bytes_written - int(_MAX_LAG_S * self.bytes_per_s)
                if lag > 0 and self._reader_behind:
                    self.bytes_dropped += lag       # a real unit does not wait for its reader
                    self.bytes_written += lag
                offset = self.bytes_written % total
                end = min(offset + due - self.bytes_written, total, offset + _MAX_WRITE)
                self.bytes_written += self._write(self.data[offset:end])
        except BaseException as exc:  # noqa: BLE001 - reported through .error, thread must end
            if not self._stop.is_set():
                self.error = exc

    def _write(self, chunk: bytes) -> int:
        """Write what the pty takes now (a full pty is a reader that is behind: wait)."""
        _, writable, _ = select.select([], [self._master_fd], [], _POLL_S)
        self._reader_behind = not writable
        if not writable:
            return 0
        try:
            return os.write(self._master_fd, chunk)
        except BlockingIOError:
            self._reader_behind = True
            return 0
        except OSError as exc:
            if exc.errno == errno.EIO and self._stop.is_set():
                return 0
            raise
