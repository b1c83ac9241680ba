"""Run every benchmark once and print their tables (what `make bench` does)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCHMARKS = [
    ["bench_model.py"],
    ["bench_gyro_stream.py"],
    ["bench_allan.py"],
    ["bench_noise_id.py"],
    ["bench_allan_stream.py"],
    ["bench_report.py"],
    ["bench_dry_run.py"],
    ["bench_imu_dry_run.py"],
    ["bench_discrepancy.py"],
    ["bench_discrepancy_overnight.py"],
]


def main() -> int:
    failed = []
    for command in BENCHMARKS:
        print(f"\n== {' '.join(command)} ==", flush=True)
        code = subprocess.call([sys.executable, str(HERE / command[0]), *command[1:]])
        if code:
            failed.append(command[0])
    if failed:
        print(f"\nfailed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
