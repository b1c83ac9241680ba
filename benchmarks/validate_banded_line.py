"""The part-of-the-record line test (analysis/discrepancy/banded_line.py) alone: false alarms, detection, cost.

Each draw simulates a log on a profile, refits the nominal model (nothing is
searched: what the test sees is what the workflow's final refit leaves when
nothing is named) and runs the test. Cases:

* ``control``: nothing hidden (the false-alarm rate; ≤ 0.5 % is the budget);
* ``rate``: a tone at 0.29·fs with amplitude ∝ |ω| (``banded_line_cases.rate_line``), ‖s‖ = ``--size``·σ;
* ``top``: the same tone with amplitude ∝ |ω|⁶ (essentially at the top rates only);
* ``cooling``: a tone at 0.17·fs only while the chamber cools;
* ``constant``: a constant tone at 0.23·fs (periodic_interference's shape: must *not* fire);
* a catalogue effect at 10σ not in the refitted model (must not fire).

Prints one row per profile and case with the test's CPU time. ``--timing N`` times the
test on a record of N samples at 250 Hz (the overnight folder's rate).

    .venv/bin/python benchmarks/validate_banded_line.py --profiles Q2,P1 --cases control,rate --draws 100
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import time

import banded_line_cases as cases  # noqa: E402
import discrepancy_scenarios as scenarios  # noqa: E402
from threadpoolctl import threadpool_limits
from validate_noise_level import hidden_of, profile  # noqa: E402

from gyrocal.analysis.discrepancy.banded_line import (
    banded_line,
    banded_scan,
    high_passed,
    record_parts,
)
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.noise_model import NoiseModel

OWN_CASES = ("control", "rate", "top", "cooling", "constant")


def extra_of(case: str, prof: scenarios.Profile, size: float):
    fs = prof.fs_hz
    if case == "rate":
        return cases.rate_line(prof, 0.29, size)
    if case == "top":
        return cases.rate_line(prof, 0.29, size, power=6.0)
    if case == "cooling":
        return cases.cooling_line(prof, 0.17 * fs, size)
    if case == "constant":
        return cases.constant_line(prof, 0.23 * fs, size)
    return None


def scan_of(ctx: Context, after):
    log = ctx.log
    return banded_scan(high_passed(ctx.resid_full(after), ctx.bins.samples_per_bin), ctx.fs_hz, ctx.noise,
                       0.5 / ctx.bins.width_s, record_parts(log.table_rate_dps, log.chamber_temp_c, ctx.fs_hz))


def run(pname: str, case: str, draws: int, seed0: int, size: float, verbose: bool) -> tuple[int, int, float]:
    """(present, present and part-only) out of ``draws``, and the test's mean CPU seconds."""
    prof = profile(pname)
    hidden = [] if case in OWN_CASES else hidden_of(case, prof)
    extra = extra_of(case, prof, size)
    present = fires = 0
    cpu = 0.0
    for seed in range(seed0, seed0 + draws):
        log = scenarios.as_measured_log(scenarios.simulate_log(prof, hidden, seed, extra_dph=extra))
        model = scenarios.nominal_model()
        ctx = Context(model, log, seed, 300, 1000)
        ctx.use_noise(NoiseModel.of_model(model))
        after = ctx.fit(model)
        start = time.process_time()
        line = scan_of(ctx, after)
        cpu += time.process_time() - start
        present += bool(line and line.present)
        fires += bool(line and line.part_only)
        if verbose and line is not None and (line.present or line.score > 0.7 * line.threshold):
            print(f"  seed {seed}: {line.describe()}; part-only {line.part_only}", flush=True)
    return present, fires, cpu / draws


def timing(n_samples: int) -> None:
    fs = 250.0
    prof = scenarios.procedure_profile(n_samples / fs, fs, ramps_c_per_min=(1.0, 2.0, 1.0), dwell_s=60.0,
                                       static_s=600.0)
    log = scenarios.as_measured_log(scenarios.simulate_log(prof, [], 1))
    model = scenarios.nominal_model()
    ctx = Context(model, log, 1, 300, 2000)
    ctx.use_noise(NoiseModel.of_model(model))
    after = ctx.fit(model)
    start = time.process_time()
    ctx.resid_full(after)
    resid = time.process_time() - start
    start = time.process_time()
    _, line = banded_line(ctx, after, [])
    print(f"{len(log):,} samples at {fs:g} Hz: the workflow's call {time.process_time() - start:.2f} CPU-s "
          f"(of which the full-rate residual {resid:.2f} s), fires {line is not None}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profiles", default="P1,Q1,Q2,Q3")
    parser.add_argument("--cases", default="control,rate")
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--seed", type=int, default=9100)
    parser.add_argument("--size", type=float, default=10.0, help="‖s‖/σ of the added line")
    parser.add_argument("--timing", type=int, default=0, help="time the test on a record of N samples")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        if args.timing:
            timing(args.timing)
            return
        print("| profile | case | draws | line present | present and part-only (fires) | CPU per test (s) |\n"
              "|---|---|---|---|---|---|")
        for pname in args.profiles.split(","):
            for case in args.cases.split(","):
                present, fires, cpu = run(pname, case, args.draws, args.seed, args.size, args.verbose)
                print(f"| {pname} | {case} | {args.draws} | {present} | {fires} | {cpu:.3f} |", flush=True)


if __name__ == "__main__":
    main()
