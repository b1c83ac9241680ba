"""Dry run of the three-mounting IMU calibration: plan ETA, wall time, matrix against truth.

``procedures/imu-5-temps-3-mountings.yaml`` on the simulated IMU station
(real Modbus/SCPI/pty servers, the fixture turning by itself at each of the
15 remounts), timed as a whole process with its report; then every scale
factor and misalignment element of the report beside the version-2 model's
truth at the measured temperature.

    .venv/bin/python benchmarks/bench_imu_dry_run.py
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
PROCEDURE = "procedures/imu-5-temps-3-mountings.yaml"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    from gyrocal.models.imu_model import ImuModel, load_any_model
    from gyrocal.orchestrator.plan import expand_plan
    from gyrocal.orchestrator.procedure import load_procedure

    procedure = load_procedure(REPO / PROCEDURE)
    plan = expand_plan(procedure)
    model = load_any_model(procedure.station.simulation.gyro_model)
    assert isinstance(model, ImuModel)
    with tempfile.TemporaryDirectory(prefix="gyrocal-imu-") as tmp:
        out = Path(tmp) / "run"
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "gyrocal", "run", str(REPO / PROCEDURE),
                               "--sim", "--out", str(out), "--seed", str(args.seed)],
                              cwd=REPO, capture_output=True, text=True)
        wall_s = time.perf_counter() - start
        peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        if proc.returncode not in (0, 1):
            print(proc.stdout, proc.stderr, file=sys.stderr)
            return proc.returncode
        results = json.loads((out / "report" / "results.json").read_text())

    print(f"procedure               {PROCEDURE}")
    print(f"steps                   {len(plan.steps)} ({sum(s.kind == 'remount' for s in plan.steps)} remounts)")
    print(f"plan ETA                {plan.total_s / 3600:.2f} h")
    print(f"wall time incl. report  {wall_s:.1f} s ({plan.total_s / wall_s:,.0f}× real time)")
    print(f"peak RSS                {peak_kib / 1024:.0f} MiB")
    print()
    print(f"{'temp °C':>8}  {'worst |ΔSF| ppm':>16}  {'worst |ΔE| µrad':>16}  {'largest u(SF) ppm':>18}  "
          f"{'largest u(E) µrad':>18}")
    for t in results["imu"]["temperatures"]:
        sf = model.scale_factor(t["temp_c"])
        e = model.misalignment_rad(t["temp_c"]) * 1e6
        d_sf = max(abs(t["scale_factor"][a] / sf[i] - 1) * 1e6 for i, a in enumerate("xyz"))
        d_e = max(abs(t["misalignment_urad"][a + b] - e[i, j])
                  for i, a in enumerate("xyz") for j, b in enumerate("xyz") if i != j)
        print(f"{t['temp_c']:>8.2f}  {d_sf:>16.3f}  {d_e:>16.3f}  "
              f"{max(t['u_scale_factor_ppm'].values()):>18.3f}  "
              f"{max(t['u_misalignment_urad'].values()):>18.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
