"""Is a gyro stream physically possible? n samples take n / fs of time, and the counter follows time.

A gyro streams at its sample rate; nothing upstream can make it faster. So
after a flush at wall time ``t0``, by wall time ``t`` at most
``fs × speed × (t − t0)`` frames can have been produced (``speed`` is the
clock's speed: 1 on hardware, 20 for a simulated station run at 20× — its
gyro emits 20× as many frames per wall second). Bytes already in flight at
the flush (USB-serial FIFO, kernel buffer) add a bounded amount on top:
``slack_s`` of stream plus ``slack_frames``.

Two ways a block can break that bound, both bad data (journaled, the step
repeated), never samples:

* **too fast**: more samples than time allows — stale frames replayed from a
  buffer (the ``--speed 1`` bug: 40,000 samples of a 20 s step in 0.1 s);
* **counter ahead of time**: the datagram counter (unwrapped frame index)
  advanced further than time allows — a counter jump, frames that cannot
  belong to this stream position.

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
                 slack_s: float = 0.5, slack_frames: int = 2048) -> None:
        if not sample_rate_hz > 0 or not speed > 0:
            raise ValueError("sample_rate_hz and speed must be > 0")
        self.frames_per_wall_s = float(sample_rate_hz) * float(speed)
        self.rel_tol = float(rel_tol)
        self.slack_frames = self.frames_per_wall_s * float(slack_s) + int(slack_frames)
        self.start(0.0)

    def start(self, wall_s: float) -> None:
        """The stream was flushed at ``wall_s``: count from here."""
        self._t0 = float(wall_s)
        self._samples = 0
        self._first_index: int | None = None

    def allowed_frames(self, wall_s: float) -> float:
        elapsed = max(0.0, float(wall_s) - self._t0)
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
                f"{allowed:.0f} (stale or replayed frames)", self._samples, span, allowed, elapsed)
        if span > allowed:
            return Implausible(
                f"datagram counter advanced {span} frames in {elapsed:.3f} s wall, at most "
                f"{allowed:.0f} possible (counter jump)", self._samples, span, allowed, elapsed)
        return None
