"""Exact overlapping Allan deviation of a record of any length, in bounded memory.

A 72 h characterisation at 2 kHz is 5·10⁸ samples (4 GB as float64): it does
not fit a report process, and it must not be thinned (an Allan curve computed
on block averages or on a subset of start points is an approximation a
metrologist would have to be told about). This module computes the textbook
fully overlapping estimator — every start point, every τ — from a stream of
rate blocks, in three sequential passes:

1. **mean**: count and sum, in fixed blocks of :data:`MEAN_BLOCK` samples
   added in order (removing the mean before integrating keeps the phase small,
   as allantools does; the fixed blocking makes the result independent of how
   the source happens to be chunked);
2. **phase**: x[0] = 0, x[k] = τ0·Σ_{i<k}(y_i − ȳ), a running sum carried
   across blocks (bit-identical to one ``np.cumsum`` over the whole record),
   written to a :class:`PhaseStore` — the array itself for in-memory data, a
   temporary float64 file for streams (the operating system's page cache, not
   the process, holds it); the decimated phase points the noise-type
   identification needs are picked up on the way;
3. **sums**: the phase is walked in blocks of :data:`BLOCK` samples. Every τ
   with BLOCK + 2m ≤ :data:`WINDOW` is evaluated on one rolling window
   x[s … s+B+2m); longer τ read x[s+m…] and x[s+2m…] separately. Peak
   memory is the window plus two blocks, whatever the record's length.

The sums use the tiled kernels of :mod:`gyrocal.analysis.allan.kernel`; tiles
are aligned to global sample indices and added in order, so the streamed
result is bit-for-bit the in-memory one (tests check this).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrocal.analysis.allan.kernel import TILE, three_stream_sum, window_sums

#: Phase samples per block of the sums pass (32 MiB of float64); a multiple of TILE.
BLOCK = 1 << 22
#: Phase samples held for the short τ (320 MiB): every m with BLOCK + 2m ≤ WINDOW
#: (m ≤ 18 M samples, 2.5 h at 2 kHz) is evaluated from it without extra reads.
WINDOW = 40 << 20
#: Samples per block of the mean: fixed, so the mean does not depend on the source's chunking.
MEAN_BLOCK = 1 << 20
#: Decimated points per τ kept for noise-type identification (see noise_id).
ALPHA_POINTS = 100_000

assert BLOCK % TILE == 0

#: A re-iterable source of rate blocks: each call yields the record from its start.
RateBlocks = Callable[[], Iterable[np.ndarray]]


class PhaseStore:
    """Where the phase lives between the passes: read(start, count) → float64 view."""

    n_phase: int

    def read(self, start: int, count: int, out: np.ndarray | None = None) -> np.ndarray:
        raise NotImplementedError

    def close(self) -> None:
        """Release the storage (a temporary file is deleted)."""


class MemoryPhase(PhaseStore):
    """The phase of an in-memory record: one array of N+1 values, read as views."""

    def __init__(self, n_phase: int) -> None:
        self.array = np.empty(n_phase, dtype=np.float64)
        self.n_phase = n_phase
        self._filled = 0

    def append(self, block: np.ndarray) -> None:
        if block.base is not self.array:  # a block made by claim() is already in place
            self.array[self._filled : self._filled + block.size] = block
        self._filled += block.size

    def claim(self, count: int) -> np.ndarray:
        """The next ``count`` slots, to compute the phase in place (no second copy)."""
        return self.array[self._filled : self._filled + count]

    def read(self, start: int, count: int, out: np.ndarray | None = None) -> np.ndarray:
        return self.array[start : start + count]


class FilePhase(PhaseStore):
    """The phase of a streamed record in a temporary float64 file, read with pread.

    Reads go through the page cache into a caller's buffer, so the process's
    resident memory stays at the buffers' size whatever the file's size.
    """

    def __init__(self, directory: str | Path | None = None) -> None:
        handle, name = tempfile.mkstemp(prefix="gyrocal-phase-", suffix=".f64",
                                        dir=None if directory is None else str(directory))
        self.path = Path(name)
        self._fd = handle
        self.n_phase = 0

    def append(self, block: np.ndarray) -> None:
        data = np.ascontiguousarray(block, dtype=np.float64)
        view = memoryview(data).cast("B")
        while view:
            written = os.write(self._fd, view)
            view = view[written:]
        self.n_phase += data.size

    def read(self, start: int, count: int, out: np.ndarray | None = None) -> np.ndarray:
        if out is None or out.size < count:
            out = np.empty(count, dtype=np.float64)
        target = memoryview(out[:count]).cast("B")
        offset = start * 8
        while target:
            got = os.preadv(self._fd, [target], offset)
            if got <= 0:
                raise OSError(f"{self.path}: phase file ended at byte {offset}")
            target = target[got:]
            offset += got
        return out[:count]

    def close(self) -> None:
        try:
            os.close(self._fd)
        finally:
            self.path.unlink(missing_ok=True)


def rechunk(blocks: Iterable[np.ndarray], size: int) -> Iterator[np.ndarray]:
    """The same samples in blocks of exactly ``size`` (the last may be shorter)."""
    buffer = np.empty(size, dtype=np.float64)
    filled = 0
    for block in blocks:
        block = np.asarray(block, dtype=np.float64).ravel()
        start = 0
        while start < block.size:
            take = min(size - filled, block.size - start)
            buffer[filled : filled + take] = block[start : start + take]
            filled += take
            start += take
            if filled == size:
                yield buffer
                buffer = np.empty(size, dtype=np.float64)
                filled = 0
    if filled:
        yield buffer[:filled]


@dataclass(frozen=True)
class RecordStats:
    """What the first pass learns: how many samples, their mean, the first bad one."""

    n_samples: int
    mean: float


def record_stats(blocks: Iterable[np.ndarray]) -> RecordStats:
    """Count and mean in fixed :data:`MEAN_BLOCK` blocks; refuses non-finite samples by index."""
    total = 0.0
    n = 0
    for block in rechunk(blocks, MEAN_BLOCK):
        block_sum = float(np.add.reduce(block))
        if not np.isfinite(block_sum):  # a NaN or ±inf sample makes the sum non-finite
            finite = np.isfinite(block)
            if not finite.all():
                bad = int(np.flatnonzero(~finite)[0])
                raise ValueError(f"rate data has a non-finite value at sample {n + bad}: "
                                 f"{block[bad]}")
            raise ValueError(f"rate data sum overflows near sample {n}")
        total += block_sum
        n += block.size
    if n == 0:
        raise ValueError("no rate samples")
    return RecordStats(n, total / n)


def write_phase(blocks: Iterable[np.ndarray], stats: RecordStats, rate_hz: float,
                store: MemoryPhase | FilePhase, m_values: np.ndarray | None = None
                ) -> list[np.ndarray]:
    """Second pass: the phase into ``store``.

    Returns, per m of ``m_values`` (none when None), the decimated phase
    x[0], x[m], …, x[k·m] with k ≤ min(N//m, :data:`ALPHA_POINTS`): the
    non-overlapping τ-averages noise identification needs.
    """
    m_list = [] if m_values is None else [int(m) for m in m_values]
    wanted = [min(stats.n_samples // m, ALPHA_POINTS) + 1 for m in m_list]
    decimated = [np.empty(w) for w in wanted]
    taken = [0] * len(m_list)
    scale = 1.0 / float(rate_hz)
    carry = 0.0
    first = np.zeros(1)
    store.append(first)
    _pick(first, 0, m_list, wanted, decimated, taken)
    written = 1
    for block in blocks:
        block = np.asarray(block, dtype=np.float64)
        if block.size == 0:
            continue
        if isinstance(store, MemoryPhase):
            body = np.subtract(block, stats.mean, out=store.claim(block.size))
        else:
            body = block - stats.mean
        body[0] += carry  # the running sum continues exactly as one cumsum would
        np.cumsum(body, out=body)
        carry = float(body[-1])
        body *= scale
        store.append(body)
        _pick(body, written, m_list, wanted, decimated, taken)
        written += body.size
    if written != stats.n_samples + 1:
        raise ValueError(f"the record changed between passes: {stats.n_samples} then "
                         f"{written - 1} samples")
    return decimated


def _pick(block: np.ndarray, offset: int, m_list: list[int], wanted: list[int],
          decimated: list[np.ndarray], taken: list[int]) -> None:
    """Copy the phase points k·m that fall inside this block (strided slices, no gathers)."""
    end = offset + block.size
    for j, m in enumerate(m_list):
        k = taken[j]
        if k >= wanted[j] or k * m >= end:
            continue
        count = min(wanted[j] - k, (end - 1 - k * m) // m + 1)
        local = k * m - offset
        decimated[j][k : k + count] = block[local : local + (count - 1) * m + 1 : m]
        taken[j] = k + count


def second_difference_totals(store: PhaseStore, m_values: np.ndarray,
                             block: int = BLOCK, window: int = WINDOW,
                             compiled: bool = True) -> np.ndarray:
    """Σ_i (x[i+2m] − 2x[i+m] + x[i])² for each m, walking the phase block by block.

    A τ is *short* when block + 2m fits the ``window``: its three reads share
    one window x[s … s+block+2m), which rolls forward (the overlap is moved,
    only the new block is read), so the phase is read about once for all of
    them. A *long* τ reads x[s+m…] and x[s+2m…] separately: two more passes
    over the phase each, which is what bounds the time of a record that does
    not fit in memory (README, "Measured figures").
    """
    if block % TILE:
        raise ValueError(f"block {block} is not a multiple of the tile ({TILE})")
    n_phase = store.n_phase
    m_values = np.asarray(m_values, dtype=np.int64)
    if isinstance(store, MemoryPhase):  # one window: the array is already here
        block = max(block, -(-n_phase // TILE) * TILE)
        window = block + 2 * int(m_values.max(initial=0))
    window = max(window, block)
    short = block + 2 * m_values <= window
    m_short, m_long = m_values[short], m_values[~short]
    totals_short = np.zeros(m_short.size)
    totals_long = np.zeros(m_long.size)
    rolling = None if isinstance(store, MemoryPhase) else _RollingWindow(store, window)
    stream_bufs = (np.empty(block), np.empty(block)) if m_long.size and rolling else None
    for start in range(0, n_phase, block):
        counts = np.clip(n_phase - 2 * m_short - start, 0, block)
        need = min(block if m_long.size else 0, n_phase - start)
        if counts.size and counts.max() > 0:
            need = max(need, int(np.max(np.where(counts > 0, counts + 2 * m_short, 0))))
        view = store.read(start, need) if rolling is None else rolling.read(start, need)
        if counts.size and counts.max() > 0:
            window_sums(view, counts, m_short, totals_short, compiled=compiled)
        for j, m in enumerate(m_long):
            m = int(m)
            count = int(min(block, n_phase - 2 * m - start))
            if count <= 0:
                continue
            b_buf, c_buf = stream_bufs if stream_bufs is not None else (None, None)
            b = store.read(start + m, count, b_buf)
            c = store.read(start + 2 * m, count, c_buf)
            totals_long[j] = three_stream_sum(view[:count], b, c, count, totals_long[j],
                                              compiled=compiled)
    totals = np.empty(m_values.size)
    totals[short] = totals_short
    totals[~short] = totals_long
    return totals


class _RollingWindow:
    """x[start … start+count) of a phase file, reusing what the previous window already read."""

    def __init__(self, store: PhaseStore, size: int) -> None:
        self.store = store
        self.buffer = np.empty(size)
        self.start = 0
        self.filled = 0

    def read(self, start: int, count: int) -> np.ndarray:
        keep = self.start + self.filled - start
        if keep > 0 and start >= self.start:
            keep = min(keep, count)
            offset = start - self.start
            self.buffer[:keep] = self.buffer[offset : offset + keep]  # numpy handles the overlap
        else:
            keep = 0
        if count > keep:
            self.store.read(start + keep, count - keep, self.buffer[keep:count])
        self.start, self.filled = start, count
        return self.buffer[:count]
