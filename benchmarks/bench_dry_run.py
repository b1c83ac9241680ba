"""Dry run of the overnight procedure against the simulated instruments, timed as a whole.

The real protocol servers (Modbus chamber, ACUTROL table, gyro on a pty) run in
the same process as the orchestrator on simulated time; this measures how
many times faster than real time a night passes, and the peak memory, for
the README. The reference it beats is the wall clock: the procedure's ETA.

    .venv/bin/python benchmarks/bench_dry_run.py
    .venv/bin/python benchmarks/bench_dry_run.py --procedure procedures/smoke.yaml
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--procedure", default="procedures/fog-overnight-sf-temperature.yaml")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    sys.path.insert(0, str(REPO))
    from gyrocal.orchestrator.plan import expand_plan
    from gyrocal.orchestrator.procedure import load_procedure

    procedure = load_procedure(REPO / args.procedure)
    plan = expand_plan(procedure)
    fs_hz = procedure.defaults.sample_rate_hz
    with tempfile.TemporaryDirectory(prefix="gyrocal-dry-run-") as tmp:
        out = Path(tmp) / "run"
        start = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "gyrocal", "run", str(REPO / args.procedure), "--sim",
             "--out", str(out), "--seed", str(args.seed)],
            cwd=REPO, capture_output=True, text=True)
        wall_s = time.perf_counter() - start
        peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        if proc.returncode not in (0, 1):
            print(proc.stdout, proc.stderr, file=sys.stderr)
            return proc.returncode
        events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
        samples = sum(e.get("samples", 0) for e in events if e["event"] == "step_completed")
        manifest = json.loads((out / "manifest.json").read_text())
        data_mib = sum(p.stat().st_size for p in (out / "samples").rglob("*.parquet")) / 2**20
        results = json.loads((out / "report" / "results.json").read_text())

    rows = [
        ("procedure", args.procedure),
        ("steps", f"{len(plan.steps)}"),
        ("procedure time (ETA)", f"{plan.total_s / 3600:.2f} h"),
        ("gyro rate", f"{fs_hz:g} Hz"),
        ("samples logged", f"{samples:,} ({samples / fs_hz / 3600:.2f} h)"),
        ("sample data written", f"{data_mib:.0f} MiB Parquet"),
        ("run state", manifest["state"]),
        ("wall time incl. report", f"{wall_s:.1f} s"),
        ("speed-up vs real time", f"{plan.total_s / wall_s:,.0f}×"),
        ("peak RSS", f"{peak_kib / 1024:.0f} MiB"),
    ]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    print()
    print(_truth_table(procedure, results))
    return 0


def _truth_table(procedure, results: dict) -> str:
    """The report's figures beside the simulated gyro's model (the known truth)."""
    from gyrocal.models.gyro_model import load_model

    sim = procedure.station.simulation
    if sim is None:
        return ""
    model = load_model(sim.gyro_model)
    reference = min(results["scale_factor"], key=lambda e: abs(e["temp_c"] - model.reference_temp_c))
    sf_truth = 1.0 + 1e-6 * (model.sf_error_ppm + model.sf_tempco_ppm_per_c
                             * (reference["sensor_temp_c"] - model.reference_temp_c))
    rows = [
        ("SF at the reference temperature", reference["sf"], sf_truth),
        ("SF sensitivity (ppm/°C)", results["sf_temperature"]["sensitivity_ppm_per_c"],
         model.sf_tempco_ppm_per_c),
        ("bias sensitivity (deg/h/°C)", results["bias_temperature"]["sensitivity_dph_per_c"],
         model.bias_tempco_dph_per_c),
        ("ARW N (deg/√h)", results["allan"]["fit"]["N_deg_per_rth"], model.noise.arw_deg_per_rth),
        ("bias instability B (deg/h)", results["allan"]["fit"]["B_dph"],
         model.noise.bias_instability_dph),
    ]
    lines = [f"{'figure (report vs simulated truth)':<34}  {'report':>12}  {'truth':>12}"]
    lines += [f"{name:<34}  {got:>12.7g}  {truth:>12.7g}" for name, got, truth in rows]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
