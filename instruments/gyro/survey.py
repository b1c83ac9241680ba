"""Which datagram a STIM300 stream carries, and at what rate, read from the bytes alone.

A unit sends the one normal-mode type it is configured for (TS1524
Table 5-21) and nothing in the stream says which but the identifier byte
and the CRC. Every type (with and without CR LF) is tried on the same bytes;
the one whose CRC-valid datagrams explain the most bytes is the stream's.
A wrong declaration would otherwise look like line corruption (every frame
a CRC error or garbage). The sample rate follows from the counter's step
(§7.5.2.2.18: it counts 2000 Hz internal samples, so fs = 2000 / step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro.datagram import FrameDecoder
from gyrocal.instruments.gyro.datagram_types import (
    INTERNAL_RATE_HZ,
    NORMAL_MODE_TYPES,
    FrameLayout,
    layout_of,
)


@dataclass(frozen=True)
class StreamSurvey:
    """What the bytes show: the datagram type and the counter step (None when no datagram)."""

    layout: FrameLayout | None
    frames_valid: int
    counter_step: int | None      # most common counter difference between consecutive datagrams
    bytes_examined: int

    @property
    def sample_rate_hz(self) -> float | None:
        """2000 / counter step (TS1524 §7.5.2.2.18), None without two datagrams."""
        return None if not self.counter_step else INTERNAL_RATE_HZ / self.counter_step

    def describe(self) -> str:
        """``0x93 (rate, acceleration, inclination) with CR LF`` for messages."""
        if self.layout is None:
            return "no STIM300 normal-mode datagram"
        return self.layout.kind.label() + (" with CR LF" if self.layout.crlf else "")


def survey_stream(data: bytes | bytearray | memoryview) -> StreamSurvey:
    """Try every normal-mode type on ``data``; the one explaining the most bytes wins.

    A CR LF stream also checks as the same type without CR LF (the
    terminator then reads as garbage), and its last datagram may still lack
    its terminator; so CR LF is chosen when it finds all the datagrams the
    plain reading finds but the last. A plain stream read with CR LF finds
    almost none (its terminators are not there).
    """
    buf = bytes(data)
    best: tuple[int, FrameLayout | None, np.ndarray] = (0, None, np.empty(0, np.uint8))
    present = set(buf)
    for identifier in NORMAL_MODE_TYPES:
        if identifier not in present:
            continue
        plain = FrameDecoder(datagram=identifier, crlf=False).feed(buf)
        terminated = FrameDecoder(datagram=identifier, crlf=True).feed(buf)
        crlf = len(terminated) > 0 and len(terminated) >= len(plain) - 1
        decoded = terminated if crlf else plain
        layout = layout_of(identifier, crlf)
        explained = len(decoded) * layout.length
        if explained > best[0]:
            best = (explained, layout, decoded.counter)
    _, layout, counter = best
    return StreamSurvey(layout, int(counter.size), dominant_counter_step(counter), len(buf))


def dominant_counter_step(counter: np.ndarray) -> int | None:
    """The most common counter difference (mod 256) between consecutive datagrams."""
    if counter.size < 2:
        return None
    steps = np.diff(np.asarray(counter, dtype=np.uint8))
    values, counts = np.unique(steps, return_counts=True)
    step = int(values[np.argmax(counts)])
    return step or 256
