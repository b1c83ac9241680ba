"""What the live page plots, read from the run's Parquet chunks as they land.

Conditions (chamber temperature, table rate) come from each chunk's Parquet
column statistics (the footer, not the data), so a night of chunks costs a few
kilobytes per look; the gyro signal of the current step comes from its latest
chunks, decimated to what a browser can draw. Both are read through the run
record's one chunk reader (``record/samples.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.app.watch.snapshot import PlanStep
from gyrocal.record.journal import JournalEvent
from gyrocal.record.run_folder import RunFolderError
from gyrocal.record.samples import chunk_columns, chunk_ranges


@dataclass(frozen=True)
class ChunkStats:
    step_id: str
    t_start_s: float
    t_end_s: float
    chamber_c: float
    table_dps: float


_stats_cache: dict[tuple[str, int], ChunkStats | None] = {}


def _chunk_stats(path: Path, step_id: str) -> ChunkStats | None:
    try:
        key = (str(path), path.stat().st_mtime_ns)
    except FileNotFoundError:
        return None
    except OSError as exc:          # e.g. `samples` is a file: NotADirectoryError
        raise _damaged(path, exc) from None
    if key not in _stats_cache:
        try:
            _stats_cache[key] = _read_stats(path, step_id)
        except FileNotFoundError:
            return None
    return _stats_cache[key]


def _damaged(path: Path, exc: OSError) -> RunFolderError:
    """A chunk the journal names that cannot be reached: name it, and what the system said."""
    return RunFolderError(f"{path}: cannot be read as a sample chunk "
                          f"({exc.strerror or type(exc).__name__}); the run folder is damaged")


def _read_stats(path: Path, step_id: str) -> ChunkStats | None:
    ranges = chunk_ranges(path)
    if not {"t_s", "chamber_temp_c", "table_rate_dps"} <= ranges.keys():
        return None
    (t0, t1), (c0, c1), (r0, r1) = (ranges[n] for n in ("t_s", "chamber_temp_c", "table_rate_dps"))
    return ChunkStats(step_id, t0, t1, 0.5 * (c0 + c1), 0.5 * (r0 + r1))


#: Chunks of one logged step follow each other within a sample period; a longer pause
#: between chunks is time with nothing logged.
UNLOGGED_GAP_S = 1.0


def conditions(run_dir: Path, events: list[dict[str, Any]], plan: list[PlanStep]
               ) -> dict[str, list[float | None]]:
    """Measured chamber °C and table °/s per chunk beside the plan's values for its step.

    Where nothing was logged (ramps, soaks, spin-ups between logged steps) a row of nulls
    is put in, so the plot draws a gap instead of a line across time nobody measured (a
    diagonal from -500 to +10 deg/s over an hour of soak reads as a table decelerating)."""
    by_step = {s.step_id: s for s in plan}
    out: dict[str, list[float | None]] = {"t_s": [], "chamber_c": [], "plan_c": [],
                                          "table_dps": [], "plan_dps": []}
    last_end_s: float | None = None
    for event in events:
        if event.get("event") != JournalEvent.CHUNK_WRITTEN or "path" not in event:
            continue
        step_id = str(event.get("step_id", ""))
        stats = _chunk_stats(Path(run_dir) / str(event["path"]), step_id)
        if stats is None:
            continue
        step = by_step.get(step_id)
        if last_end_s is not None and stats.t_start_s - last_end_s > UNLOGGED_GAP_S:
            for name, values in out.items():
                values.append(0.5 * (last_end_s + stats.t_start_s) if name == "t_s" else None)
        last_end_s = stats.t_end_s
        for t in (stats.t_start_s, stats.t_end_s):
            out["t_s"].append(t)
            out["chamber_c"].append(stats.chamber_c)
            out["table_dps"].append(stats.table_dps)
            out["plan_c"].append(step.setpoint_c if step else None)
            out["plan_dps"].append(step.rate_dps if step else None)
    return out


def step_signal(run_dir: Path, events: list[dict[str, Any]], max_points: int = 1500,
                max_chunks: int = 4) -> dict[str, Any]:
    """The gyro output of the most recent logged step (its latest chunks), decimated."""
    chunks = [e for e in events if e.get("event") == JournalEvent.CHUNK_WRITTEN and "path" in e]
    if not chunks:
        return {"step_id": None, "t_s": [], "gyro": []}
    step_id = chunks[-1].get("step_id")
    attempt = chunks[-1].get("attempt")
    paths = [Path(run_dir) / str(e["path"]) for e in chunks
             if e.get("step_id") == step_id and e.get("attempt") == attempt][-max_chunks:]
    t_parts, g_parts = [], []
    for path in paths:
        try:
            columns = chunk_columns(path, ("t_s", "gyro"))
        except FileNotFoundError:
            continue               # a chunk being replaced right now: the next look has it
        except OSError as exc:     # e.g. `samples` is a file
            raise _damaged(path, exc) from None
        t_parts.append(columns["t_s"])
        g_parts.append(columns["gyro"])
    if not t_parts:
        return {"step_id": step_id, "t_s": [], "gyro": []}
    t_s, gyro = np.concatenate(t_parts), np.concatenate(g_parts)
    stride = max(1, len(t_s) // max_points)
    n = len(t_s) // stride * stride
    if stride > 1:   # block means: what a browser can draw, without aliasing the noise
        t_s = t_s[:n].reshape(-1, stride).mean(axis=1)
        gyro = gyro[:n].reshape(-1, stride).mean(axis=1)
    return {"step_id": step_id, "t_s": t_s.tolist(), "gyro": gyro.tolist(), "stride": stride}
