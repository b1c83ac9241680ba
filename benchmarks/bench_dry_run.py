"""Dry run of the overnight procedure against the simulated instruments, timed as a whole.

The real protocol servers (Modbus chamber, ACUTROL table, gyro on a pty) run in
the same process as the orchestrator on simulated time; this measures how
many times faster than real time a night passes, the peak memory, and where
the wall and CPU time go (start-up, conditions, logging, report) beside the
pty floor: the same frames pushed through a pty and decoded, which logging
cannot beat (``dry_run_phases.py``). Median of ``--repeat`` runs; the load
average is printed, since on a shared machine only same-session figures
compare, and CPU time (user+sys) is the steadier figure there.
``--baseline TREE`` runs another tree's dry run (a clone of main with its
own ``.venv``) interleaved with this one's, for an A/B in one session.

    .venv/bin/python benchmarks/bench_dry_run.py
    .venv/bin/python benchmarks/bench_dry_run.py --procedure procedures/smoke.yaml
    .venv/bin/python benchmarks/bench_dry_run.py --baseline /tmp/main-clone
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--procedure", default="procedures/fog-overnight-sf-temperature.yaml")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=3, help="runs; the median is reported")
    parser.add_argument("--baseline", help="another tree (with its .venv): its dry runs interleaved")
    args = parser.parse_args()

    sys.path.insert(0, str(REPO))
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from dry_run_phases import (
        load_note,
        median_runs,
        phase_table,
        pty_floor,
        run_rounds,
        summary_rows,
    )

    from gyrocal.orchestrator.plan import expand_plan
    from gyrocal.orchestrator.procedure import load_procedure

    procedure = load_procedure(REPO / args.procedure)
    plan = expand_plan(procedure)
    fs_hz = procedure.defaults.sample_rate_hz
    load_before = load_note()
    runs, baseline = run_rounds(REPO, args.procedure, args.seed, args.repeat, args.baseline)
    run = median_runs(runs)
    block_n = max(1, int(10.0 * fs_hz))          # the engine's default 10 s read block
    floor = pty_floor(run.samples, fs_hz, procedure.station.gyro.with_temperature, block_n,
                      datagram=procedure.station.gyro.datagram)

    rows = [
        ("procedure", args.procedure),
        ("steps", f"{len(plan.steps)}"),
        ("procedure time (ETA)", f"{plan.total_s / 3600:.2f} h"),
        ("gyro rate", f"{fs_hz:g} Hz"),
        ("samples logged", f"{run.samples:,} ({run.samples / fs_hz / 3600:.2f} h)"),
        ("sample data written", f"{run.data_mib:.0f} MiB Parquet"),
        ("run state", run.state),
        *summary_rows("", runs),
        ("speed-up vs real time", f"{plan.total_s / run.wall_s:,.0f}×"),
        ("phases of the median run", ""),
        *phase_table(run, floor),
        *(summary_rows("baseline ", baseline) if baseline else []),
        *([("phases of the baseline's median run", ""), *phase_table(median_runs(baseline), floor)]
          if baseline else []),
        ("machine", f"{load_before} before, {load_note()} after"),
    ]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    print()
    print(_truth_table(procedure, run.results))
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
