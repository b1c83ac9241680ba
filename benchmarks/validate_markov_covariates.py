"""Own cases for the Markov-covariate test (analysis/discrepancy/markov_covariates.py), whole workflow.

Runs the discrepancy workflow on (a) slow structure outside the catalogue tied to
a logged covariate (tests/support/markov_covariate_cases.UNKNOWNS) on the own
15-min, 400 Hz thermal-shock profile and on Q2; (b) true Markov biases at 10σ
(τ short and long) on the shock profile, P1, Q1 and Q2; (c) effect-free controls.
Prints one line per run: what was named (probability), `unexplained`, the
covariate test's verdict when it ran, CPU. Run it on two trees (before / after a
change), or with ``--before`` (the covariate test's hook let through), with the same seeds.

    .venv/bin/python benchmarks/validate_markov_covariates.py --part unknowns --seeds 2
    .venv/bin/python benchmarks/validate_markov_covariates.py --part markov --seeds 2
    .venv/bin/python benchmarks/validate_markov_covariates.py --part controls --seeds 100 --profiles shock
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import discrepancy_scenarios as scenarios  # noqa: E402
import markov_covariate_cases as cases  # noqa: E402

from gyrocal.models.gyro_model import EffectSpec

#: τ (s) of the true Markov biases per profile: one short, one long against the record
MARKOV_TAUS_S = {"shock": (12.0, 150.0), "P1": (10.0, 1000.0), "Q1": (30.0, 300.0), "Q2": (30.0, 300.0)}
UNKNOWN_SEED0 = 61000
MARKOV_SEED0 = 62000
CONTROL_SEED0 = 63000


def profile(name: str) -> scenarios.Profile:
    if name == "shock":
        return cases.shock_profile()
    if name == "P1":
        return scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import validate_discrepancy_outside as outside  # lazy: a benchmark module, only for Q1–Q3

    return outside.profile(name)


def _without_covariate_test() -> None:
    """The workflow as it was before markov_covariates.py: its hook lets every Markov reading pass."""
    from gyrocal.analysis.discrepancy import workflow  # lazy: patched in the worker process only
    from gyrocal.analysis.discrepancy.stochastic import MARKOV

    workflow.unless_tied_to_covariates = lambda *args: (MARKOV, None)


def run(job: tuple[str, str, str, int, bool]) -> str:
    part, pname, what, seed, before = job
    if before:
        _without_covariate_test()
    result, cpu = analyse_case(part, profile(pname), what, seed, cases.sized_unknown)
    named = ", ".join(f"{f.name} {f.probability:.2f}" for f in result.found) or "-"
    covariate = next((n for n in result.notes if "markov_bias not named" in n), "")
    return (f"{part}|{pname}|{what}|{seed}|named: {named}|unexplained {result.unexplained}|"
            f"cpu {cpu:.1f}|{covariate[:220]}|where: {result.where[:160]}")


def analyse_case(part: str, prof: scenarios.Profile, what: str, seed: int, sized_unknown):
    """One case of a Markov-safeguard benchmark: an unknown shape (``sized_unknown`` at 10σ), a true
    10σ Markov bias of τ ``what`` s, or a control; the workflow's result and its CPU seconds."""
    hidden: list[EffectSpec] = []
    extra = None
    if part == "unknowns":
        extra = sized_unknown(what, prof, 10.0, seed)
    elif part == "markov":
        hidden = [scenarios.sized_markov(10.0, float(what), prof)]
    start = time.process_time()
    result = scenarios.analyse_scenario(prof, hidden, seed, extra_dph=extra)
    return result, time.process_time() - start


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
    parser.add_argument("--part", choices=("unknowns", "markov", "controls"), required=True)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--profiles", default="shock")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--before", action="store_true",
                        help="without the covariate test (the workflow before markov_covariates.py)")
    args = parser.parse_args()
    start = time.time()
    with ProcessPoolExecutor(args.workers) as pool:
        for line in pool.map(run, jobs(args)):
            print(line, flush=True)
    print(f"# {time.time() - start:.0f} s wall", flush=True)


if __name__ == "__main__":
    main()
