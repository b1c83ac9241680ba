"""Every shipped procedure, dry-run twice with one seed, compared (issue 30).

Runs ``gyrocal run PROC --sim --seed N`` twice for each procedure in
``procedures/`` (in full, as shipped) and compares the two run folders as
``tests/orchestrator/test_shipped_dry_runs.py`` does
(``tests/support/dry_run_compare.py``): sample chunks byte for byte and dtype
per column, the journal apart from wall times, hash chain, run identity and
loopback addresses, results.json apart from run identity and wall times.
Prints one row per procedure (wall time of each run, chunks, differences)
and exits 1 if any pair differs.

    .venv/bin/python benchmarks/check_dry_run_determinism.py
    .venv/bin/python benchmarks/check_dry_run_determinism.py --only smoke tilt-linearity
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def dry_run(procedure: Path, seed: int, out: Path) -> tuple[int, float]:
    """Exit status and wall time of one dry run, in its own process."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "gyrocal", "run", str(procedure), "--sim",
                           "--seed", str(seed), "--out", str(out)],
                          cwd=REPO, capture_output=True, text=True)
    if done.returncode not in (0, 1):
        sys.stderr.write(done.stderr[-2000:])
    return done.returncode, time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--only", nargs="*", help="procedure names (file stems) to check")
    parser.add_argument("--keep", help="a folder to keep the run folders in")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO))
    from tests.support.dry_run_compare import columns, differences

    procedures = sorted((REPO / "procedures").glob("*.yaml"))
    if args.only:
        procedures = [p for p in procedures if p.stem in args.only]
    work = Path(args.keep or tempfile.mkdtemp(prefix="dry-run-determinism-"))
    print(f"{datetime.date.today()}  seed {args.seed}  load {os.getloadavg()[0]:.1f}  "
          f"{os.cpu_count()} cores")
    print(f"{'procedure':<32} {'exit':>5} {'run 1 s':>8} {'run 2 s':>8} {'chunks':>6}  identical")
    failed = False
    for procedure in procedures:
        outs = [work / procedure.stem / name for name in ("first", "second")]
        runs = [dry_run(procedure, args.seed, out) for out in outs]
        codes = "/".join(str(code) for code, _ in runs)
        if any(code not in (0, 1) for code, _ in runs):
            verdict, failed = "run failed", True
        else:
            found = differences(*outs)
            failed = failed or bool(found)
            verdict = "yes" if not found else f"NO: {len(found)}: " + "; ".join(found[:4])
        chunks = len(columns(outs[0])) if (outs[0] / "samples").is_dir() else 0
        print(f"{procedure.stem:<32} {codes:>5} {runs[0][1]:>8.1f} {runs[1][1]:>8.1f} "
              f"{chunks:>6}  {verdict}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
