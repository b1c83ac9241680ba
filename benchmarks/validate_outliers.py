"""The spike test (analysis/discrepancy/outliers.py) alone: false alarms, detection, cost.

Each draw simulates a log on a profile, refits the nominal model (the base
numbers; nothing is searched, so what the test sees is what the workflow's
final refit leaves when nothing is named) and runs the test. Cases:

* ``control``: nothing hidden (the false-alarm rate; ≤ 0.5 % is the budget);
* ``outliers``: 3–8 single-sample outliers of 8–30σ, heavy-tailed sizes
  (``tests/support/outlier_cases.py``; ``outliers:5:10`` for 5–10σ);
* ``doubled``: a sample's angle increment counted twice every 4.1 s while the table turns
  (spikes of ω); ``doubled_small``: the same at a fraction sized to 10σ at the top rate
  (``doubled_small:6`` for 6σ);
* a catalogue effect at 10σ (dead_zone 2 deg/s, quantization 1″, markov_bias:τ, or any
  sized effect), *not* in the refitted model, so the test sees it raw: it must not fire.

Profiles as ``validate_noise_level.py`` (P1–P3, Q1–Q3, L1, L2). Prints one row per
profile and case with the CPU time of the test itself. ``--timing N`` instead times the
test on a record of N samples at 250 Hz (the overnight folder's rate); ``--white N`` runs it on
``--draws`` records of N samples of pure Gaussian white noise (the calibration itself);
``--workflow 61,62`` runs the whole workflow on each case and seed with the test and with it
made never to fire (before/after on the same code; catalogue effects must be unchanged).

    .venv/bin/python benchmarks/validate_outliers.py --profiles P1,Q1,Q2,Q3 --cases control --draws 100
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import contextlib
import time

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np
import outlier_cases as cases  # noqa: E402
from threadpoolctl import threadpool_limits
from validate_noise_level import hidden_of, profile  # noqa: E402

import gyrocal.analysis.discrepancy.workflow as workflow_module
from gyrocal.analysis.discrepancy.outliers import spike_test, spikes_in

SPIKE_CASES = ("control", "outliers", "doubled", "doubled_small")


def extra_of(case: str, prof: scenarios.Profile, seed: int) -> np.ndarray | None:
    """The case's spikes (deg/h per sample); ``outliers:lo:hi`` and ``doubled_small:σ`` set the sizes."""
    kind, *sizes = case.split(":")
    if kind == "outliers":
        return cases.outliers_dph(prof, seed, *(float(x) for x in sizes))
    if kind == "doubled":
        return cases.doubled_dph(prof)
    if kind == "doubled_small":
        return cases.doubled_dph(prof, cases.doubled_fraction_for(prof, float(sizes[0]) if sizes else 10.0))
    return None


def run(pname: str, case: str, draws: int, seed0: int) -> tuple[int, float, str]:
    """Fires out of ``draws``, the test's mean CPU seconds, and the last firing description."""
    prof = profile(pname)
    hidden = [] if case.split(":")[0] in SPIKE_CASES else hidden_of(case, prof)
    fires, cpu, said = 0, 0.0, ""
    for seed in range(seed0, seed0 + draws):
        model = scenarios.nominal_model()
        if case == "quantization":              # the workflow names it from the output lattice first
            model = model.with_effect(hidden[0])
        ctx, after = scenarios.base_refit(prof, seed, hidden, extra_of(case, prof, seed), model=model)
        start = time.process_time()
        spikes = spike_test(ctx, after)
        cpu += time.process_time() - start
        fires += spikes.fires
        said = spikes.description if spikes.fires else said
    return fires, cpu / draws, said


def workflow(pname: str, case: str, seeds: list[int]) -> None:
    """The whole workflow on a case, with and without the spike test (before/after on the same code)."""
    prof = profile(pname)
    hidden = [] if case.split(":")[0] in SPIKE_CASES else hidden_of(case, prof)
    for seed in seeds:
        row = []
        for label, active in (("before", False), ("after", True)):
            with _spike_test(active):
                result = scenarios.analyse_scenario(prof, hidden, seed, max_bins=1000,
                                                    extra_dph=extra_of(case, prof, seed))
            named = ", ".join(f"{f.name} {f.probability:.2f}" for f in result.found) or "–"
            row.append(f"{label}: {named}, unexplained {result.unexplained}")
        fired = any("single-sample spike" in n and "no single-sample" not in n for n in result.notes)
        print(f"| {pname} | {case} | {seed} | {row[0]} | {row[1]} | {'fired' if fired else '–'} |", flush=True)


@contextlib.contextmanager
def _spike_test(active: bool):
    """The workflow with the spike test (``active``) or without it ("before": its result untouched)."""
    if active:
        yield
        return
    real = workflow_module.with_spikes
    workflow_module.with_spikes = lambda ctx, after, result: result
    try:
        yield
    finally:
        workflow_module.with_spikes = real


def white_null(n_samples: int, draws: int, seed: int) -> None:
    """The test on pure Gaussian white noise (the noise model's sample-level part exactly), at rest.

    A direct check of the threshold's calibration with many more draws than the simulated logs allow.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) / 100.0
    rate = np.zeros(n_samples)
    fires = sum(spikes_in(rng.standard_normal(n_samples), t, rate, 100.0).fires for _ in range(draws))
    print(f"white noise, {n_samples:,} samples: fired {fires} of {draws} ({100.0 * fires / draws:.2f} %)")


def timing(n_samples: int) -> None:
    fs = 250.0
    spikes, test_s, resid_s, n = scenarios.timed_residual_test(spike_test, n_samples, fs)
    print(f"{n:,} samples at {fs:g} Hz: the test {test_s:.2f} CPU-s "
          f"(after the full-rate residual, {resid_s:.2f} s), fires {spikes.fires}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profiles", default="P1,Q1,Q2,Q3")
    parser.add_argument("--cases", default="control,outliers,doubled,doubled_small")
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--seed", type=int, default=9300)
    parser.add_argument("--timing", type=int, default=0, help="time the test on a record of N samples")
    parser.add_argument("--workflow", default="", help="seeds (a,b,…): the whole workflow before/after")
    parser.add_argument("--white", type=int, default=0, help="the test on N-sample white-noise records")
    args = parser.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        if args.timing:
            timing(args.timing)
            return
        if args.workflow:
            print("| profile | case | seed | before | after | spike test |\n|---|---|---|---|---|---|")
            for pname in args.profiles.split(","):
                for case in args.cases.split(","):
                    workflow(pname, case, [int(x) for x in args.workflow.split(",")])
            return
        if args.white:
            white_null(args.white, args.draws, args.seed)
            return
        print("| profile | case | draws | fired | CPU per test (s) | last description |\n|---|---|---|---|---|---|")
        for pname in args.profiles.split(","):
            for case in args.cases.split(","):
                fires, cpu, said = run(pname, case, args.draws, args.seed)
                print(f"| {pname} | {case} | {args.draws} | {fires} | {cpu:.3f} | {said} |", flush=True)


if __name__ == "__main__":
    main()
