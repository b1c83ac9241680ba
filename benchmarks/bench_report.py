"""Time build_report on a synthetic overnight run folder written with the project's writers.

The folder is the overnight procedure (procedures/fog-overnight-sf-temperature.yaml:
6 temperatures, ± sweeps to 500 deg/s, a 3 h Allan hold) expanded by the
planner, with every logged step written as Parquet chunks through RunFolder and
journalled like the engine does. The samples are synthetic (SF·rate + bias +
white noise), which is all the report's speed depends on; simulating the
instruments would only make the set-up slower. Prints the data size, the
set-up time and the report time (target ≤ 15 s).

    .venv/bin/python benchmarks/bench_report.py              # 500 Hz
    .venv/bin/python benchmarks/bench_report.py --fs 2000    # the top of the 200–2000 Hz range
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.record.journal import sha256_file
from gyrocal.record.plan_record import write_plan_record
from gyrocal.record.run_folder import RunFolder

ROOT = Path(__file__).resolve().parents[1]
CHUNK_S = 600.0


def make_run(out: Path, fs_hz: float, seed: int) -> int:
    procedure = load_procedure(ROOT / "procedures" / "fog-overnight-sf-temperature.yaml")
    plan = expand_plan(procedure)
    folder = RunFolder.create(out, procedure.path, procedure.station.path,
                              manifest_fields={"mode": "sim", "operator": "bench",
                                               "steps": [s.step_id for s in plan.steps]})
    record = write_plan_record(out, procedure, plan)
    # the record states the procedure's rate; the bench may log at another
    data = json.loads(record.read_text())
    data["sample_rate_hz"] = fs_hz
    record.write_text(json.dumps(data, indent=2) + "\n")
    folder.update_manifest(plan_sha256=sha256_file(record))
    journal = folder.open_journal()
    rng = np.random.default_rng(seed)
    total = 0
    t0 = 0.0
    for step in plan.steps:
        journal.append("step_started", step_id=step.step_id, attempt=1, kind=step.kind)
        if step.kind not in ("static", "allan", "dwell"):
            journal.append("step_completed", step_id=step.step_id, attempt=1)
            continue
        n = int(round(step.duration_s * fs_hz))
        chunks = []
        per_chunk = int(CHUNK_S * fs_hz)
        for index, start in enumerate(range(0, n, per_chunk)):
            rows = min(per_chunk, n - start)
            t = t0 + (start + np.arange(rows)) / fs_hz
            temp = np.full(rows, step.setpoint_c)
            sf = 1.0 + 1e-6 * (50 + 20 * (step.setpoint_c - 25.0))
            gyro = sf * step.rate_dps + (2.0 + rng.standard_normal(rows) * 0.6 * np.sqrt(fs_hz)) / 3600
            gyro = np.round(gyro / 6.103515625e-05) * 6.103515625e-05
            chunk = folder.write_chunk(step.step_id, 1, index, {
                "t_s": t, "table_rate_dps": np.full(rows, step.rate_dps), "chamber_temp_c": temp,
                "gyro": gyro, "sensor_temp_c": temp, "table_angle_deg": step.rate_dps * (t - t0)})
            journal.append("chunk_written", step_id=step.step_id, attempt=1, path=chunk.path,
                           sha256=chunk.sha256, rows=chunk.rows)
            chunks.append(chunk.path)
        t0 += n / fs_hz
        total += n
        journal.append("step_completed", step_id=step.step_id, attempt=1, samples=n,
                       lost_frames=0, crc_errors=0, chunks=chunks)
    folder.close()
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fs", type=float, default=500.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", help="write the run folder here and keep it")
    args = parser.parse_args()
    from gyrocal.reports.build import build_report

    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-report-")) / "run"
    try:
        start = time.perf_counter()
        samples = make_run(out, args.fs, args.seed)
        setup_s = time.perf_counter() - start
        size = sum(p.stat().st_size for p in (out / "samples").rglob("*.parquet"))
        start = time.perf_counter()
        results = build_report(out)
        report_s = time.perf_counter() - start
        allan = results["allan"]
        print(f"steps logged: {len(results['steps'])}, samples: {samples / 1e6:.1f} M at "
              f"{args.fs:g} Hz ({samples / args.fs / 3600:.1f} h), parquet {size / 1e6:.0f} MB")
        print(f"set-up (writing the folder): {setup_s:.1f} s")
        print(f"build_report: {report_s:.2f} s (target <= 15 s); Allan on "
              f"{allan['n_samples'] / 1e6:.1f} M samples, {len(allan['tau_s'])} taus, "
              f"{allan['method']}")
        print(f"N fitted {allan['fit']['N_deg_per_rth']:.4g} deg/rt(h) (synthetic truth 0.01)")
    finally:
        if not args.keep:
            shutil.rmtree(out.parent, ignore_errors=True)


if __name__ == "__main__":
    main()
