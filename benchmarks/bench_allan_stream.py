"""Exact overlapping ADEV of a 72 h, 2 kHz log (518.4 M samples) streamed from Parquet.

What it measures, in one run:

1. writes a synthetic gyro-like rate log (white noise + rate random walk +
   bias, deg/h) as Parquet files of 10 minutes each (1.2 M samples) — 432
   files, 4.1 GB — unless they are already in --dir;
2. runs ``gyrocal analyze allan FILES… --rate-hz 2000`` as a child process on
   the first 1, 10, 40, 100, 216 and all 432 files (the scaling from 1.2 M
   to 518.4 M samples), recording wall time and the child's peak resident
   memory (the operating system's accounting, ru_maxrss);
3. checks exactness: the streamed curve of the first 42 files (50.4 M
   samples) against the in-memory float64 computation of the same samples,
   value by value (they are expected to be bit-identical).

    .venv/bin/python benchmarks/bench_allan_stream.py --dir /var/tmp/allan72h
    .venv/bin/python benchmarks/bench_allan_stream.py --files 40    # quick: 48 M samples
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RATE_HZ = 2000.0
FILE_SAMPLES = 1_200_000  # 10 minutes at 2 kHz
FULL_FILES = 432          # 72 h
SCALING = (1, 10, 40, 100, 216, 432)
EXACT_FILES = 42          # 50.4 M samples


def _args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", default=None, help="where the Parquet log is (made if missing)")
    parser.add_argument("--files", type=int, default=FULL_FILES, help="files to use (≤ 432)")
    parser.add_argument("--seed", type=int, default=72)
    parser.add_argument("--keep", action="store_true", help="keep the log for the next run")
    return parser.parse_args()


def _write_log(folder: Path, files: int, seed: int) -> list[Path]:
    """The synthetic log, file by file (bounded memory), deterministic from the seed."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"rate-{i:04d}.parquet" for i in range(files)]
    marker = folder / f"complete-{files}-{seed}"
    if marker.exists():
        return paths
    rng = np.random.default_rng(seed)
    walk = 0.0
    n_arw, k_rrw = 0.01, 0.05  # deg/√h, deg/h/√h
    for i, path in enumerate(paths):
        white = rng.standard_normal(FILE_SAMPLES) * (n_arw * 60.0 * np.sqrt(RATE_HZ))
        steps = rng.standard_normal(FILE_SAMPLES) * (k_rrw * np.sqrt(1.0 / RATE_HZ / 3600.0))
        rrw = walk + np.cumsum(steps)
        walk = float(rrw[-1])
        rate = 2.0 + white + rrw
        t = (np.arange(FILE_SAMPLES) + i * FILE_SAMPLES) / RATE_HZ
        pq.write_table(pa.table({"t_s": t, "gyro": rate}), path, compression="none")
    marker.touch()
    return paths


def _analyse(paths: list[Path], out: Path) -> tuple[float, int, dict]:
    """Wall seconds, peak RSS bytes (the child's own) and the JSON of one analyze run."""
    command = [sys.executable, "-m", "gyrocal", "analyze", "allan", *map(str, paths),
               "--units", "deg/h", "--json", str(out)]
    start = time.perf_counter()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    stderr = child.stderr.read().decode() if child.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"analyze allan failed: {stderr}")
    return wall, usage.ru_maxrss * 1024, json.loads(out.read_text())


def _exactness(paths: list[Path], streamed: dict) -> tuple[int, float]:
    """Streamed vs in-memory float64 on the same samples: count of unequal τ, max rel diff."""
    import pyarrow.parquet as pq

    from gyrocal.analysis.allan.summary import allan_curve

    y = np.concatenate([pq.read_table(p, columns=["gyro"]).column("gyro").to_numpy()
                        for p in paths])
    curve = allan_curve(y, RATE_HZ)
    ours = np.array(streamed["adev_dph"])
    if curve.adev.size != ours.size or not np.array_equal(curve.tau_s, streamed["tau_s"]):
        raise SystemExit("τ grids differ between the streamed and in-memory curves")
    unequal = int(np.count_nonzero(curve.adev != ours))
    return unequal, float(np.max(np.abs(ours / curve.adev - 1.0)))


def main() -> None:
    args = _args()
    files = min(args.files, FULL_FILES)
    folder = Path(args.dir) if args.dir else Path(tempfile.mkdtemp(prefix="gyrocal-allan72h-"))
    start = time.perf_counter()
    paths = _write_log(folder, files, args.seed)
    size_gb = sum(p.stat().st_size for p in paths) / 1e9
    print(f"log: {files} Parquet files, {files * FILE_SAMPLES:,} samples at {RATE_HZ:g} Hz, "
          f"{size_gb:.1f} GB ({time.perf_counter() - start:.0f} s to write or find)")
    print(f"cores: {os.cpu_count()}   load average: {os.getloadavg()[0]:.2f}")
    print(f"{'samples':>13} {'hours':>6} {'τ':>4} {'wall s':>8} {'M samples/s':>12} "
          f"{'peak RSS MiB':>13}")
    results = {}
    with tempfile.TemporaryDirectory() as scratch:
        for count in [c for c in SCALING if c <= files] + ([files] if files not in SCALING
                                                           else []):
            out = Path(scratch) / f"allan-{count}.json"
            wall, peak, curve = _analyse(paths[:count], out)
            n = count * FILE_SAMPLES
            results[count] = curve
            print(f"{n:>13,} {n / RATE_HZ / 3600:>6.1f} {len(curve['tau_s']):>4} {wall:>8.1f} "
                  f"{n / wall / 1e6:>12.1f} {peak / 2**20:>13.0f}", flush=True)
        if files >= EXACT_FILES:
            out = Path(scratch) / "allan-exact.json"
            _, _, streamed = _analyse(paths[:EXACT_FILES], out)
            unequal, max_rel = _exactness(paths[:EXACT_FILES], streamed)
            print(f"exactness, {EXACT_FILES * FILE_SAMPLES:,} samples streamed vs in memory "
                  f"(float64): {unequal} of {len(streamed['tau_s'])} τ differ, max relative "
                  f"difference {max_rel:.1e}")
    if not args.keep and not args.dir:
        for p in folder.iterdir():
            p.unlink()
        folder.rmdir()


if __name__ == "__main__":
    main()
