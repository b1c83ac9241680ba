"""Own cases for the deterministic-shape test of a Markov reading (analysis/discrepancy/markov_shapes.py).

Runs the discrepancy workflow on (a) deterministic slow structure outside the
catalogue (tests/support/markov_shape_cases.UNKNOWNS: staircases and hinges in T,
a sign(ω)-dependent T term, turn-ons, steps, a held random walk, a bump, a cubic
in T) on the own 10-min, 250 Hz temperature loop and on other profiles; (b) true
Markov biases at 10σ (τ short and long against the record); (c) effect-free
controls. One line per run: what was named (probability), `unexplained`, the
refusal note when one was made, CPU. ``--before`` lets every Markov reading pass
the shape test (the workflow before markov_shapes.py), with the same seeds.

    .venv/bin/python benchmarks/validate_markov_shapes.py --part unknowns --seeds 3 --profiles loop,shock
    .venv/bin/python benchmarks/validate_markov_shapes.py --part markov --seeds 2 --profiles loop,shock,P1,Q1,Q2
    .venv/bin/python benchmarks/validate_markov_shapes.py --part controls --seeds 100 --profiles loop
    .venv/bin/python benchmarks/validate_markov_shapes.py --part level --seeds 80 --profiles loop:400,Q2:300

``--part level`` runs the test alone (the nominal model refitted to a simulated log with a
10σ Markov bias of the given τ, the Markov test fitted as the workflow does) and counts refusals.
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import discrepancy_scenarios as scenarios  # noqa: E402
import markov_shape_cases as cases  # noqa: E402
import validate_markov_covariates as covariates  # noqa: E402

#: τ (s) of the true Markov biases per profile: short and long against the record
MARKOV_TAUS_S = {"loop": (8.0, 60.0, 400.0), "ladder": (6.0, 45.0, 300.0), **covariates.MARKOV_TAUS_S}
UNKNOWN_SEED0 = 71000
MARKOV_SEED0 = 72000
CONTROL_SEED0 = 73000
LEVEL_SEED0 = 75000


def profile(name: str) -> scenarios.Profile:
    if name == "loop":
        return cases.loop_profile()
    return cases.ladder_profile() if name == "ladder" else covariates.profile(name)


def _without_shape_test() -> None:
    """The workflow before markov_shapes.py: its hook lets every Markov reading pass."""
    from gyrocal.analysis.discrepancy import workflow  # lazy: patched in the worker process only
    from gyrocal.analysis.discrepancy.stochastic import MARKOV

    workflow.unless_deterministic_shape = lambda *args: (MARKOV, None)


def run(job: tuple[str, str, str, int, bool]) -> str:
    part, pname, what, seed, before = job
    if before:
        _without_shape_test()
    result, cpu = covariates.analyse_case(part, profile(pname), what, seed, cases.sized_unknown)
    named = ", ".join(f"{f.name} {f.probability:.2f}" for f in result.found) or "-"
    refusal = next((n for n in result.notes if "markov_bias not named" in n), "")
    return (f"{part}|{pname}|{what}|{seed}|named: {named}|unexplained {result.unexplained}|"
            f"cpu {cpu:.1f}|{refusal[:200]}")


def level(pname: str, tau_s: float, records: int) -> str:
    """How often the shape test alone refuses a true 10σ Markov bias of ``tau_s`` on ``pname``."""
    from gyrocal.analysis.discrepancy.context import markov_test  # lazy: only for --part level
    from gyrocal.analysis.discrepancy.markov_shapes import shape_test

    prof = profile(pname)
    hidden = [scenarios.sized_markov(10.0, tau_s, prof)]
    refused, cpu = [], []
    for k in range(records):
        ctx, fit = scenarios.base_refit(prof, LEVEL_SEED0 + k, hidden)
        markov = markov_test(ctx, fit)
        start = time.process_time()
        verdict = shape_test(ctx, fit, markov)
        cpu.append(time.process_time() - start)
        if verdict.why is not None:
            refused.append(LEVEL_SEED0 + k)
    return (f"level|{pname}|τ {tau_s:g} s|refused {len(refused)}/{records} {refused}|"
            f"CPU per call median {sorted(cpu)[len(cpu) // 2]:.2f} s")


def jobs(args) -> list[tuple[str, str, str, int, bool]]:
    out = []
    for pname in args.profiles.split(","):
        for k in range(args.seeds):
            if args.part == "unknowns":
                out += [("unknowns", pname, name, UNKNOWN_SEED0 + k, args.before) for name in cases.UNKNOWNS]
            elif args.part == "markov":
                out += [("markov", pname, str(tau), MARKOV_SEED0 + k, args.before) for tau in MARKOV_TAUS_S[pname]]
            else:
                out.append(("controls", pname, "-", CONTROL_SEED0 + k, args.before))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("unknowns", "markov", "controls", "level"), required=True)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--profiles", default="loop")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--before", action="store_true", help="without the shape test")
    args = parser.parse_args()
    start = time.time()
    if args.part == "level":
        for item in args.profiles.split(","):
            pname, tau = item.split(":")
            print(level(pname, float(tau), args.seeds), flush=True)
        return
    with ProcessPoolExecutor(args.workers) as pool:
        for line in pool.map(run, jobs(args)):
            print(line, flush=True)
    print(f"# {time.time() - start:.0f} s wall", flush=True)


if __name__ == "__main__":
    main()
