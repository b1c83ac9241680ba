"""Shared by the dry-run benchmarks: a timed dry run, its phases, and the pty floor beside it.

A dry run's wall time splits, from the wall times its journal records, into
start-up (imports, simulators, connect: process start to ``run_started``),
conditions (ramps, soaks, remounts: steps that log nothing), logging (the
logged steps: gyro through the pty, decoding, chamber and table polls,
Parquet chunks) and the report (``steps_done`` to ``report_written``). The
same split is made of CPU time (user+sys): the child's ``/proc/PID/stat``
is sampled every :data:`_CPU_SAMPLE_S` and read at the journal's phase
boundaries; CPU time is what compares on a machine shared with other jobs,
where wall time mostly measures the neighbours. The pty floor is what
logging cannot beat: the same number of frames, encoded once beforehand,
pushed through a pseudo-terminal by a writer thread and decoded by the
STIM300 driver in the run's block size.
"""

from __future__ import annotations

import json
import os
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
from gyrocal.instruments.gyro.datagram_types import counter_step, counter_values
from gyrocal.instruments.gyro.stim300 import Stim300Gyro

LOGGED_KINDS = ("static", "allan", "dwell")
_CPU_SAMPLE_S = 0.02            # how often the child's CPU time is sampled for the phase split
_CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


@dataclass(frozen=True)
class DryRun:
    """One timed dry run of a procedure (a whole ``gyrocal run --sim`` process)."""

    wall_s: float
    cpu_s: float           # user + sys of the run's process: steadier than wall on a shared machine
    peak_rss_mib: float
    phases_s: dict[str, float]
    cpu_phases_s: dict[str, float]     # user+sys seconds per phase (sampled, see module doc)
    samples: int
    data_mib: float
    state: str
    results: dict


def timed_dry_run(repo: Path, procedure: str, seed: int, python: str | None = None) -> DryRun:
    """Run ``procedure`` with ``--sim --seed`` in a child process; time it and split it.

    ``repo``: the tree to run, from its folder; ``python``: that tree's interpreter
    (default: this one, for this tree).
    """
    with tempfile.TemporaryDirectory(prefix="gyrocal-dry-run-") as tmp:
        out = Path(tmp) / "run"
        start_wall = time.time()
        start = time.perf_counter()
        log_path = Path(tmp) / "output.txt"
        with log_path.open("w") as log:
            proc = subprocess.Popen(
                [python or sys.executable, "-m", "gyrocal", "run", str(repo / procedure), "--sim",
                 "--out", str(out), "--seed", str(seed)], cwd=repo, stdout=log,
                stderr=subprocess.STDOUT)
            cpu_series, status, rusage = _sample_cpu(proc.pid)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall_s = time.perf_counter() - start
        if proc.returncode not in (0, 1):
            raise RuntimeError(f"dry run failed ({proc.returncode}):\n{log_path.read_text()}")
        cpu_s = rusage.ru_utime + rusage.ru_stime
        events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
        data_mib = sum(p.stat().st_size for p in (out / "samples").rglob("*.parquet")) / 2**20
        results = json.loads((out / "report" / "results.json").read_text())
        state = json.loads((out / "manifest.json").read_text())["state"]
    samples = sum(e.get("samples", 0) for e in events if e["event"] == "step_completed")
    wall_phases = phases(events, start_wall, wall_s)
    return DryRun(wall_s, cpu_s, rusage.ru_maxrss / 1024, wall_phases,
                  cpu_phases(events, cpu_series, cpu_s), samples, data_mib, state, results)


def _sample_cpu(pid: int):
    """Sample ``pid``'s CPU time until it exits, then reap it.

    Returns ([(wall time, CPU s)], wait status, its rusage). The child is reaped
    here (``os.wait4``), so its own CPU time and peak RSS are exact, not the
    running maximum over all children.
    """
    series: list[tuple[float, float]] = []
    stat = Path(f"/proc/{pid}/stat")
    while True:
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            break
        if fields[0] == "Z":        # exited, not yet reaped: its last sample stands
            break
        series.append((time.time(), (int(fields[11]) + int(fields[12])) / _CLOCK_TICKS))
        time.sleep(_CPU_SAMPLE_S)
    _, status, rusage = os.wait4(pid, 0)
    return series, status, rusage


def _phase_bounds(events: list[dict]) -> dict:
    """Wall times of the phase boundaries, and the (start, end) of every logged attempt."""
    def first(name: str) -> float:
        return next(e["wall_time"] for e in events if e["event"] == name)

    logged: list[tuple[float, float]] = []
    started: dict[str, float] = {}
    kinds: dict[str, str] = {}
    for e in events:
        if e["event"] == "step_started":
            started[e["step_id"]] = e["wall_time"]
            kinds[e["step_id"]] = e.get("kind", "")
        elif (e["event"] in ("step_completed", "step_bad") and e.get("step_id") in started
              and kinds.get(e["step_id"]) in LOGGED_KINDS):
            logged.append((started.pop(e["step_id"]), e["wall_time"]))
    return {"logged": logged, **{name: first(name) for name in
                                 ("run_started", "steps_done", "report_written")}}


def phases(events: list[dict], start_wall: float, wall_s: float) -> dict[str, float]:
    """Wall seconds per phase, from the journal's wall times."""
    bounds = _phase_bounds(events)
    logging_s = sum(end - begin for begin, end in bounds["logged"])
    run_started, steps_done = bounds["run_started"], bounds["steps_done"]
    return {
        "start-up": run_started - start_wall,
        "conditions": (steps_done - run_started) - logging_s,
        "logging": logging_s,
        "report": bounds["report_written"] - steps_done,
        "close": wall_s - (bounds["report_written"] - start_wall),
    }


def cpu_phases(events: list[dict], series: list[tuple[float, float]], cpu_s: float
               ) -> dict[str, float]:
    """CPU seconds per phase: the sampled CPU time at the journal's phase boundaries."""
    times = np.array([t for t, _ in series] or [0.0])
    cpu = np.array([c for _, c in series] or [0.0])

    def at(wall: float) -> float:
        return float(np.interp(wall, times, cpu))

    bounds = _phase_bounds(events)
    out = {"start-up": at(bounds["run_started"])}
    out["logging"] = sum(at(end) - at(begin) for begin, end in bounds["logged"])
    out["conditions"] = at(bounds["steps_done"]) - out["start-up"] - out["logging"]
    out["report"] = at(bounds["report_written"]) - at(bounds["steps_done"])
    out["close"] = cpu_s - at(bounds["report_written"])
    return {name: out[name] for name in ("start-up", "conditions", "logging", "report", "close")}


@dataclass(frozen=True)
class PtyFloor:
    """What pushing a run's frames through a pty and decoding them costs, at the least."""

    wall_s: float
    cpu_s: float        # user+sys of this process (writer thread and reader) meanwhile


def pty_floor(n_frames: int, fs_hz: float, with_temperature: bool, block_n: int,
              datagram: int | None = None) -> PtyFloor:
    """Push ``n_frames`` pre-encoded frames through a pty and decode them; wall and CPU.

    ``datagram``: the station's type (TS1524 Table 5-21); an IMU's 0xA7 frames are 59
    bytes, 0x94's 25, and the pty's cost goes with the bytes.
    """
    period = 256 * 1024                       # a whole number of counter cycles: seamless repeats
    rate = np.zeros((period, 3))
    rate[:, 0] = np.random.default_rng(0).normal(0.0, 1.0, period)
    temp = np.full((period, 3), 25.0) if with_temperature else None
    # the datasheet's counter at this rate (TS1524 §7.5.2.2.18), or the driver's stream
    # check refuses the stream as the wrong rate
    counter = counter_values(np.arange(period, dtype=np.int64), counter_step(fs_hz))
    data = encode_frame_array(rate, counter, temp_c=temp, datagram=datagram).tobytes()
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
                       timeout_s=30.0, datagram=datagram)
    try:
        writer = threading.Thread(target=write, daemon=True)
        cpu_before = os.times()
        start = time.perf_counter()
        writer.start()
        got = 0
        while got < n_frames:
            got += len(gyro.read_samples(min(block_n, n_frames - got)))
        writer.join()
        elapsed_s = time.perf_counter() - start
        cpu_after = os.times()
    finally:
        gyro.close()
        os.close(master)
        os.close(slave)
    cpu_s = (cpu_after.user - cpu_before.user) + (cpu_after.system - cpu_before.system)
    return PtyFloor(elapsed_s, cpu_s)


def median_runs(runs: list[DryRun]) -> DryRun:
    """The run with the median wall time (its phases and memory are reported with it)."""
    ordered = sorted(runs, key=lambda r: r.wall_s)
    return ordered[len(ordered) // 2]


def phase_table(run: DryRun, floor: PtyFloor) -> list[tuple[str, str]]:
    """Per phase: wall and CPU seconds; the pty floor beside logging."""
    rows = [(f"  {name}", f"{seconds:5.1f} s wall  {run.cpu_phases_s[name]:5.1f} s CPU")
            for name, seconds in run.phases_s.items()]
    rows.append(("  pty floor (same frames: pty + decode)",
                 f"{floor.wall_s:5.1f} s wall  {floor.cpu_s:5.1f} s CPU"))
    return rows


def run_rounds(repo: Path, procedure: str, seed: int, repeat: int, baseline: str | None
               ) -> tuple[list[DryRun], list[DryRun]]:
    """``repeat`` runs of this tree and, with ``baseline`` (another tree, e.g. a clone of
    main, with its own ``.venv``), as many of the baseline's, interleaved (B, A, B, A, …)
    so both see the same load on a shared machine."""
    runs: list[DryRun] = []
    before: list[DryRun] = []
    for _ in range(repeat):
        if baseline:
            tree = Path(baseline).resolve()
            before.append(timed_dry_run(tree, procedure, seed, python=str(tree / ".venv/bin/python")))
        runs.append(timed_dry_run(repo, procedure, seed))
    return runs, before


def summary_rows(label: str, runs: list[DryRun]) -> list[tuple[str, str]]:
    """Wall, CPU and peak memory of a set of runs: medians and every value."""
    def listed(values: list[float]) -> str:
        return ", ".join(f"{v:.1f}" for v in values)
    walls = [r.wall_s for r in runs]
    cpus = [r.cpu_s for r in runs]
    peaks = [r.peak_rss_mib for r in runs]
    return [
        (f"{label}wall time incl. report", f"{median(walls):.1f} s (median of {len(runs)}: {listed(walls)})"),
        (f"{label}CPU time (user+sys)", f"{median(cpus):.1f} s (median of {len(runs)}: {listed(cpus)})"),
        (f"{label}peak RSS", f"{max(peaks):.0f} MiB (largest; all: {listed(peaks)})"),
    ]


def load_note() -> str:
    """The 1-minute load average over the core count: the benchmark is relative on a shared box."""
    load1, load5, _ = os.getloadavg()
    return f"load average {load1:.1f} / {load5:.1f} (1 / 5 min) on {os.cpu_count()} cores"


def median(values: list[float]) -> float:
    return statistics.median(values)
