"""Is a gyro stream physically possible? n samples take n / fs of time, and the counter follows time.

A gyro streams at its sample rate; nothing upstream can make it faster. So
if every frame of a step was sampled after wall time ``since`` (the table
confirmed at its rate), by wall time ``t`` at most ``fs × speed × (t − since)``
frames can have arrived (``speed`` is the clock's speed: 1 on hardware, 20
for a simulated station run at 20× — its gyro emits 20× as many frames per
wall second). The datagram counter is the gyro's own sample clock, so the
count is taken from it (the unwrapped frame index, lost frames included), not
from how many frames the host happened to receive.

Without a confirmation time the step starts at the flush, and the bytes in
flight at the flush (a USB-serial FIFO releases on a 16 ms latency timer)
are allowed ``slack_s`` of stream; ``slack_frames`` absorbs rounding.

Two ways a block can break that bound, both bad data (journaled, the step
repeated), never samples:

* **too fast**: more samples than time allows — stale frames: frames sampled
  before the step began, e.g. while the table was still accelerating, that
  reached the host only after its flush (a simulated gyro starved of CPU on
  a loaded host, issue 28: the first 80-90 samples of a dwell were the end
  of the table's ramp, SF 1400-3000 ppm off), or a buffer replayed (the
  ``--speed 1`` bug: 40,000 samples of a 20 s step in 0.1 s);
* **counter ahead of time**: the datagram counter advanced further than time
  allows — a counter jump, or stale frames of which some were lost.

Too slow is not checked here: a stream that falls behind runs into the
read timeout, which already faults.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Implausible:
    """Why a block cannot be real (for the journal)."""

    reason: str
    samples: int
    frame_span: int
    allowed_frames: float
    wall_s: float


class StreamPlausibility:
    """Cumulative check of one flushed stream against wall time (see the module docstring)."""

    def __init__(self, sample_rate_hz: float, speed: float = 1.0, rel_tol: float = 0.05,
                 slack_s: float = 0.05, slack_frames: int = 16) -> None:
        if not sample_rate_hz > 0 or not speed > 0:
            raise ValueError("sample_rate_hz and speed must be > 0")
        self.frames_per_wall_s = float(sample_rate_hz) * float(speed)
        self.rel_tol = float(rel_tol)
        self.slack_s = float(slack_s)
        self.slack_frames = int(slack_frames)
        self.start(0.0)

    def start(self, wall_s: float, since_wall_s: float | None = None) -> None:
        """The stream was flushed at ``wall_s``: count from here.

        ``since_wall_s``: the frames may have been sampled from then on (the
        table was confirmed at the step's rate then); default: ``slack_s``
        before the flush.
        """
        self._t0 = float(wall_s)
        since = self._t0 - self.slack_s if since_wall_s is None else float(since_wall_s)
        self._since = min(since, self._t0)
        self._samples = 0
        self._first_index: int | None = None

    def allowed_frames(self, wall_s: float) -> float:
        elapsed = max(0.0, float(wall_s) - self._since)
        return self.frames_per_wall_s * elapsed * (1.0 + self.rel_tol) + self.slack_frames

    def check(self, wall_s: float, n_samples: int, first_index: int | None, last_index: int | None
              ) -> Implausible | None:
        """Account for a block received by ``wall_s``; None if it is possible, else why not."""
        self._samples += int(n_samples)
        if first_index is not None and self._first_index is None:
            self._first_index = int(first_index)
        span = 0
        if last_index is not None and self._first_index is not None:
            span = int(last_index) - self._first_index + 1
        allowed = self.allowed_frames(wall_s)
        elapsed = float(wall_s) - self._t0
        if self._samples > allowed:
            return Implausible(
                f"{self._samples} samples in {elapsed:.3f} s wall: the stream gives at most "
                f"{allowed:.0f} since the table was at rate (stale or replayed frames)", self._samples, span, allowed, elapsed)
        if span > allowed:
            return Implausible(
                f"datagram counter advanced {span} frames in {elapsed:.3f} s wall, at most "
                f"{allowed:.0f} possible since the table was at rate (counter jump or stale frames)", self._samples, span, allowed, elapsed)
        return None
