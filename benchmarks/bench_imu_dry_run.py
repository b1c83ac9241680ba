"""Dry run of the three-mounting IMU calibration: plan ETA, wall time, matrix against truth.

``procedures/imu-5-temps-3-mountings.yaml`` on the simulated IMU station
(real Modbus/SCPI/pty servers, the fixture turning by itself at each of the
15 remounts), timed as a whole process with its report; then every scale
factor and misalignment element of the report beside the version-2 model's
truth at the measured temperature. Wall and CPU time per phase beside the
pty floor, as ``bench_dry_run.py`` (``--baseline`` likewise).

    .venv/bin/python benchmarks/bench_imu_dry_run.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PROCEDURE = "procedures/imu-5-temps-3-mountings.yaml"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3, help="runs; the median is reported")
    parser.add_argument("--baseline", help="another tree (with its .venv): its dry runs interleaved")
    args = parser.parse_args()

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from dry_run_phases import (
        load_note,
        median_runs,
        phase_table,
        pty_floor,
        run_rounds,
        summary_rows,
    )

    from gyrocal.models.imu_model import ImuModel, load_any_model
    from gyrocal.orchestrator.plan import expand_plan
    from gyrocal.orchestrator.procedure import load_procedure

    procedure = load_procedure(REPO / PROCEDURE)
    plan = expand_plan(procedure)
    model = load_any_model(procedure.station.simulation.gyro_model)
    assert isinstance(model, ImuModel)
    load_before = load_note()
    runs, baseline = run_rounds(REPO, PROCEDURE, args.seed, args.repeat, args.baseline)
    run = median_runs(runs)
    wall_s, results = run.wall_s, run.results
    fs_hz = procedure.defaults.sample_rate_hz
    floor = pty_floor(run.samples, fs_hz, procedure.station.gyro.with_temperature,
                      max(1, int(10.0 * fs_hz)), datagram=procedure.station.gyro.datagram)

    print(f"procedure               {PROCEDURE}")
    print(f"steps                   {len(plan.steps)} ({sum(s.kind == 'remount' for s in plan.steps)} remounts)")
    print(f"plan ETA                {plan.total_s / 3600:.2f} h")
    print(f"speed-up vs real time   {plan.total_s / wall_s:,.0f}×")
    for name, value in summary_rows("", runs):
        print(f"{name:<40}  {value}")
    print("phases of the median run")
    for name, value in phase_table(run, floor):
        print(f"{name:<40}  {value}")
    if baseline:
        for name, value in summary_rows("baseline ", baseline):
            print(f"{name:<40}  {value}")
        print("phases of the baseline's median run")
        for name, value in phase_table(median_runs(baseline), floor):
            print(f"{name:<40}  {value}")
    print(f"machine                 {load_before} before, {load_note()} after")
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
