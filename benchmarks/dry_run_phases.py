"""Shared by the dry-run benchmarks: a timed dry run, its phases, and the pty floor beside it.

A dry run's wall time splits, from the wall times its journal records, into
start-up (imports, simulators, connect: process start to ``run_started``),
conditions (ramps, soaks, remounts: steps that log nothing), logging (the
logged steps: gyro through the pty, decoding, chamber and table polls,
Parquet chunks) and the report (``steps_done`` to ``report_written``). The
pty floor is what logging cannot beat: the same number of frames, encoded
once beforehand, pushed through a pseudo-terminal by a writer thread and
decoded by the STIM300 driver in the run's block size.
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrocal.instruments.gyro.datagram import encode_frame_array
from gyrocal.instruments.gyro.stim300 import Stim300Gyro

LOGGED_KINDS = ("static", "allan", "dwell")


@dataclass(frozen=True)
class DryRun:
    """One timed dry run of a procedure (a whole ``gyrocal run --sim`` process)."""

    wall_s: float
    cpu_s: float           # user + sys of the run's process: steadier than wall on a shared machine
    peak_rss_mib: float
    phases_s: dict[str, float]
    samples: int
    data_mib: float
    state: str
    results: dict


def timed_dry_run(repo: Path, procedure: str, seed: int) -> DryRun:
    """Run ``procedure`` with ``--sim --seed`` in a child process; time it and split it."""
    with tempfile.TemporaryDirectory(prefix="gyrocal-dry-run-") as tmp:
        out = Path(tmp) / "run"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        before_kib = before.ru_maxrss
        start_wall = time.time()
        start = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "gyrocal", "run", str(repo / procedure), "--sim",
             "--out", str(out), "--seed", str(seed)], cwd=repo, capture_output=True, text=True)
        wall_s = time.perf_counter() - start
        # ru_maxrss of children is the largest child so far: runs are ordered so that a
        # smaller one after a larger one is still reported honestly (see peak_note)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        peak_kib = after.ru_maxrss
        cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        if proc.returncode not in (0, 1):
            raise RuntimeError(f"dry run failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
        events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
        data_mib = sum(p.stat().st_size for p in (out / "samples").rglob("*.parquet")) / 2**20
        results = json.loads((out / "report" / "results.json").read_text())
        state = json.loads((out / "manifest.json").read_text())["state"]
    samples = sum(e.get("samples", 0) for e in events if e["event"] == "step_completed")
    return DryRun(wall_s, cpu_s, max(peak_kib, before_kib) / 1024, phases(events, start_wall, wall_s),
                  samples, data_mib, state, results)


def phases(events: list[dict], start_wall: float, wall_s: float) -> dict[str, float]:
    """Wall seconds per phase, from the journal's wall times."""
    def first(name: str) -> float:
        return next(e["wall_time"] for e in events if e["event"] == name)

    logging_s = 0.0
    started: dict[str, float] = {}
    kinds: dict[str, str] = {}
    for e in events:
        if e["event"] == "step_started":
            started[e["step_id"]] = e["wall_time"]
            kinds[e["step_id"]] = e.get("kind", "")
        elif (e["event"] in ("step_completed", "step_bad") and e.get("step_id") in started
              and kinds.get(e["step_id"]) in LOGGED_KINDS):
            logging_s += e["wall_time"] - started.pop(e["step_id"])
    run_started, steps_done = first("run_started"), first("steps_done")
    report = first("report_written") - steps_done
    return {
        "start-up": run_started - start_wall,
        "conditions": (steps_done - run_started) - logging_s,
        "logging": logging_s,
        "report": report,
        "close": wall_s - (first("report_written") - start_wall),
    }


def pty_floor_s(n_frames: int, fs_hz: float, with_temperature: bool, block_n: int) -> float:
    """Seconds to push ``n_frames`` pre-encoded frames through a pty and decode them."""
    period = 256 * 1024                       # a whole number of counter cycles: seamless repeats
    rate = np.zeros((period, 3))
    rate[:, 0] = np.random.default_rng(0).normal(0.0, 1.0, period)
    temp = np.full((period, 3), 25.0) if with_temperature else None
    data = encode_frame_array(rate, np.arange(period), temp_c=temp).tobytes()
    frame_len = len(data) // period
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    total = n_frames * frame_len

    def write() -> None:
        sent = 0
        while sent < total:
            chunk = data[: min(len(data), total - sent)]
            view = memoryview(chunk)
            while view:
                view = view[os.write(master, view):]
            sent += len(chunk)

    gyro = Stim300Gyro(port, sample_rate_hz=fs_hz, with_temperature=with_temperature,
                       timeout_s=30.0)
    try:
        writer = threading.Thread(target=write, daemon=True)
        start = time.perf_counter()
        writer.start()
        got = 0
        while got < n_frames:
            got += len(gyro.read_samples(min(block_n, n_frames - got)))
        elapsed_s = time.perf_counter() - start
        writer.join()
    finally:
        gyro.close()
        os.close(master)
        os.close(slave)
    return elapsed_s


def median_runs(runs: list[DryRun]) -> DryRun:
    """The run with the median wall time (its phases and memory are reported with it)."""
    ordered = sorted(runs, key=lambda r: r.wall_s)
    return ordered[len(ordered) // 2]


def phase_table(run: DryRun, floor_s: float) -> list[tuple[str, str]]:
    rows = [(f"  {name}", f"{seconds:.1f} s") for name, seconds in run.phases_s.items()]
    rows.append(("  pty floor (same frames: pty + decode)", f"{floor_s:.1f} s"))
    return rows


def load_note() -> str:
    """The 1-minute load average over the core count: the benchmark is relative on a shared box."""
    load1, load5, _ = os.getloadavg()
    return f"load average {load1:.1f} / {load5:.1f} (1 / 5 min) on {os.cpu_count()} cores"


def median(values: list[float]) -> float:
    return statistics.median(values)
