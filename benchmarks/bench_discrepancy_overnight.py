"""`gyrocal discrepancy` on the overnight dry-run folder (10 M samples at 250 Hz, 20 h), as a whole process.

Makes the folder with `gyrocal run procedures/fog-overnight-sf-temperature.yaml --sim`
unless --run-dir names one (not timed), then times the discrepancy command
(threshold calibration included) ``--repeat`` times and prints, for each run
and as the median over them, the wall time and the child's CPU time (user +
system, every thread; each run's line also splits it and gives its minor page
faults), with the load average before and after, and the largest child's
peak RSS (the dry run's counts too when the benchmark made the folder). The
system part was most of the CPU until the command kept its large arrays on
the C heap (app/heap.py: each fresh 80 MB temporary had cost the kernel its
page faults; 15.6 s → 4.4 s system, 512,000 → 75,000 faults). Issue 29's
target is "the overnight folder still ≤ 30 s": on an idle machine (load well
under the core count) the median wall time is held against it; on a shared,
loaded machine the wall time measures the other users and only the CPU time
says anything (the analysis runs its BLAS on one thread).

    .venv/bin/python benchmarks/bench_discrepancy_overnight.py --repeat 3 [--run-dir DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 30.0


def make_run_dir(run_dir: Path) -> None:
    """The overnight dry run (simulated rig, seed 1), unless the folder already holds one."""
    if (run_dir / "journal.jsonl").exists():
        return
    subprocess.run([sys.executable, "-m", "gyrocal", "run",
                    str(ROOT / "procedures/fog-overnight-sf-temperature.yaml"), "--sim",
                    "--seed", "1", "--out", str(run_dir)], check=False, stdout=subprocess.DEVNULL)


@dataclass(frozen=True)
class Timing:
    """One `gyrocal discrepancy` run: wall s, the child's user and system CPU s, its minor faults."""

    wall_s: float
    user_s: float
    system_s: float
    minor_faults: int
    code: int
    output: str

    @property
    def cpu_s(self) -> float:
        return self.user_s + self.system_s


def time_discrepancy(run_dir: Path, out_dir: Path) -> Timing:
    """Wall time, the child's CPU and page faults, exit code and output of one run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "gyrocal", "discrepancy", "--model",
                           str(ROOT / "gyro-models/nominal-fog.yaml"), "--measured", str(run_dir),
                           "--out", str(out_dir)], capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return Timing(wall, after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime,
                  after.ru_minflt - before.ru_minflt, done.returncode, done.stderr + done.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-dir", default=None)
    parser.add_argument("--repeat", type=int, default=3, help="timed runs (the median is reported)")
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="gyrocal-disc-overnight-"))
    run_dir = Path(args.run_dir) if args.run_dir else scratch / "overnight"
    make_run_dir(run_dir)
    load_before = os.getloadavg()[0]
    walls, cpus = [], []
    for k in range(args.repeat):
        run = time_discrepancy(run_dir, scratch / f"out-{k}")
        if k == 0:
            print(run.output, end="")
        print(f"run {k + 1}/{args.repeat}: {run.wall_s:.1f} s wall, {run.cpu_s:.1f} s CPU ({run.user_s:.1f} user "
              f"+ {run.system_s:.1f} system), {run.minor_faults:,} minor faults, exit {run.code}")
        if run.code != 0:
            raise SystemExit(f"gyrocal discrepancy exited {run.code}; no timing reported")
        walls.append(run.wall_s)
        cpus.append(run.cpu_s)
    wall, cpu = statistics.median(walls), statistics.median(cpus)
    load_after = os.getloadavg()[0]
    cores = os.cpu_count() or 1
    peak_gb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e6   # kB on Linux
    print(f"discrepancy on {run_dir}: median of {args.repeat}: {wall:.1f} s wall, {cpu:.1f} s CPU; "
          f"1-min load average {load_before:.1f} before, {load_after:.1f} after, {cores} cores; "
          f"peak RSS {peak_gb:.2f} GB")
    idle = max(load_before, load_after) < 0.5 * cores
    held = wall if idle else cpu
    print(f"target ≤ {TARGET_S:.0f} s: {'wall' if idle else 'CPU (machine loaded, wall not meaningful)'} "
          f"{held:.1f} s: {'holds' if held <= TARGET_S else 'does NOT hold'}")


if __name__ == "__main__":
    main()
