"""Localized bias structure (steps, bumps, bursts, pulse trains) on own cases: before and after the window scan.

The window scan (analysis/discrepancy/localized.py) reads the final refit's binned
residual for window means beyond the noise model at every dyadic scale. Its cases
here are this tool's own (own shapes and sizes, profiles P1, Q1–Q3, own seeds
31000+; never the held-out sets), sized to 10σ by the known-shape SNR of their
binned shape. One workflow run gives both sides: the result as it reaches
``with_localized`` (the workflow without the scan: the scan draws from its own
generator, so nothing before it changes) and the result after it. Measures:

* unknowns: `unexplained` before/after, `where` naming the windows, wrong claims ≥ 0.8;
* catalogue neighbours at 10σ: named first before/after, claims;
* effect-free controls: `unexplained` or a claim added by the scan;
* ``--null``: the scan alone on simulated effect-free base refits (fires / records),
  and its threshold against 20,000 fresh draws of the same null;
* ``--cpu``: the scan's CPU on a P2-sized record (930,000 samples, 2000 bins).

    .venv/bin/python benchmarks/validate_localized.py --group unknown --profiles P1,Q1,Q2,Q3 --seeds 2 --out u.jsonl
    .venv/bin/python benchmarks/validate_localized.py --table u.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

import discrepancy_scenarios as scenarios  # noqa: E402
import validate_discrepancy as inside  # noqa: E402
import validate_discrepancy_outside as outside  # noqa: E402

from gyrocal.analysis.discrepancy import harmonic_comb, localized, workflow  # noqa: E402

NEIGHBOURS = ("periodic_interference", "bias_ramp", "warmup_transient", "bias_temp_quadratic", "markov_bias",
              "thermal_lag")
MARKOV_TAU_S = 300.0
WORDS = ("localized bias structure", "not a sinusoid")


def _steps(p: scenarios.Profile, seed: int, count: int) -> np.ndarray:
    """``count`` bias steps of random sign at random times between 10 % and 90 % (their own generator)."""
    rng = np.random.default_rng(seed + 7)
    t = p.t_s - p.t_s[0]
    out = np.zeros_like(t)
    for at, sign in zip(rng.uniform(0.1, 0.9, count) * t[-1], rng.choice((-1.0, 1.0), count), strict=True):
        out += sign * (t >= at)
    return out


def _train(p: scenarios.Profile, width_s: float, period_s: float, phase_s: float) -> np.ndarray:
    t = p.t_s - p.t_s[0]
    return (((t - phase_s) % period_s) < width_s).astype(float)


def _bump(p: scenarios.Profile, centre: float, fwhm: float) -> np.ndarray:
    """A raised-cosine bump centred at ``centre`` of the record, full width at half height ``fwhm`` of it."""
    t = (p.t_s - p.t_s[0]) / (p.t_s[-1] - p.t_s[0])
    u = np.clip((t - centre) / fwhm, -1.0, 1.0)
    return 0.5 * (1.0 + np.cos(np.pi * u))


#: own shapes (per sample, deg/h before sizing); seed-dependent ones take the seed
UNKNOWN = {
    "three random bias steps": lambda p, s: _steps(p, s, 3),
    "six random bias steps": lambda p, s: _steps(p, s, 6),
    "raised-cosine bump (FWHM 3 % at 63 %)": lambda p, s: _bump(p, 0.63, 0.03),
    "45-s burst at 28 %": lambda p, s: _train(p, 45.0, 1e9, 0.28 * (p.t_s[-1] - p.t_s[0])),
    "plateau 12 % of the record at 47 %": lambda p, s: _train(p, 0.12 * (p.t_s[-1] - p.t_s[0]), 1e9,
                                                              0.47 * (p.t_s[-1] - p.t_s[0])),
    "20-s pulses every 400 s": lambda p, s: _train(p, 20.0, 400.0, 130.0),
    "4-s pulses every 75 s": lambda p, s: _train(p, 4.0, 75.0, 11.0),
    "sawtooth of period 9 min": lambda p, s: ((p.t_s - p.t_s[0]) % 540.0) / 540.0,
}


def profile(name: str) -> scenarios.Profile:
    return inside.profile(name) if name.startswith("P") else outside.profile(name)


def run(pname: str, case: str, seed: int, snr: float = 10.0) -> dict:
    prof = profile(pname)
    extra, hidden = None, []
    if case in UNKNOWN:
        extra = scenarios.sized_extra(UNKNOWN[case](prof, seed), snr, prof, max_bins=1000)
    elif case == "markov_bias":
        hidden = [scenarios.sized_markov(snr, MARKOV_TAU_S, prof)]
    elif case != "control":
        hidden = [scenarios.sized_effect(case, snr, prof, max_bins=1000)]
    seen: dict = {}
    real = localized.with_localized

    def spy(ctx, after, result):   # the result as it reaches the scan, and the scan's own verdict
        seen["before"] = result
        seen["scan"] = localized.localized_test(ctx, after)
        return real(ctx, after, result)

    workflow.with_localized = spy
    try:
        samples = scenarios.simulate_log(prof, hidden, seed, extra_dph=extra)
        start = time.process_time()
        result = workflow.analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                                  n_null=300, max_bins=1000)
        cpu = time.process_time() - start
    finally:
        workflow.with_localized = real
    before = seen["before"]
    return {"profile": pname, "case": case, "seed": seed, "snr": snr,
            "before": {"found": [[f.name, round(f.probability, 4)] for f in before.found],
                       "unexplained": before.unexplained, "where": before.where[:300]},
            "found": [[f.name, round(f.probability, 4)] for f in result.found],
            "unexplained": result.unexplained, "where": result.where[:400],
            "scan": [round(seen["scan"].statistic, 2), round(seen["scan"].threshold, 2)],
            "cpu_s": round(cpu, 2)}


def jobs(group: str, profiles: list[str], seeds: int, controls: int) -> list[tuple[str, str, int]]:
    out = []
    for p in profiles:
        if group == "unknown":
            out += [(p, c, 31000 + s) for c in UNKNOWN for s in range(seeds)]
        elif group == "neighbour":
            out += [(p, c, 31100 + s) for c in NEIGHBOURS for s in range(seeds)]
        else:
            out += [(p, "control", 31200 + s) for s in range(controls)]
    return out


def _claims(found: list, case: str) -> int:
    return sum(pr >= 0.8 and n != case for n, pr in found) > 0


def table(path: str) -> None:
    rows: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for line in Path(path).read_text().splitlines():
        r = json.loads(line)
        rows[(r["profile"], r["case"])].append(r)
    print("| profile | case | runs | before: named first / `unexplained` / wrong ≥ 0.8 | "
          "after: named first / `unexplained` (scan in `where`) / wrong ≥ 0.8 | named after | median CPU s |\n"
          "|---|---|---|---|---|---|---|")
    for (p, case), rs in rows.items():
        def first(found: list, case: str = case) -> str:
            return str(sum(bool(f) and f[0][0] == case for f in found)) if case in NEIGHBOURS else "–"
        b = [r["before"] for r in rs]
        named = ", ".join(sorted({f"{n} {pr:.2f}" for r in rs for n, pr in r["found"]})) or "–"
        print(f"| {p} | {case} | {len(rs)} | {first([x['found'] for x in b])} / "
              f"{sum(x['unexplained'] for x in b)} / {sum(_claims(x['found'], case) for x in b)} | "
              f"{first([r['found'] for r in rs])} / {sum(r['unexplained'] for r in rs)} "
              f"({sum(any(w in r['where'] for w in WORDS) for r in rs)}) / {sum(_claims(r['found'], case) for r in rs)} | "
              f"{named[:110]} | {np.median([r['cpu_s'] for r in rs]):.2f} |")


def null_check(pname: str, records: int, fresh: int = 20000) -> None:
    """Both tests alone on effect-free base refits, and their thresholds against fresh draws of one null."""
    prof = profile(pname)
    fired = [0, 0]
    for seed in range(31400, 31400 + records):
        ctx, after = scenarios.base_refit(prof, seed)
        fired[0] += localized.localized_test(ctx, after).fires
        fired[1] += harmonic_comb.comb_test(ctx, after).fires
    ctx, after = scenarios.base_refit(prof, 31399)
    chol, basis, n = ctx.whitener.chol, after.basis, ctx.bins.n_bins
    w = localized.windows(n, ctx.whitener.covariance, chol @ basis)
    wi = localized.windows(n, None, basis)
    null = localized.projected_draws(n, basis)

    def best(z: np.ndarray) -> np.ndarray:
        return np.maximum(localized.window_z2(chol @ z, w).max(axis=0), localized.window_z2(z, wi).max(axis=0))

    x = localized.family_threshold(best(null), localized._chi2_1_tail, 2 * w.start.size, localized.ALPHA_LOCALIZED)
    m = harmonic_comb.PAD * n
    comb_x = harmonic_comb.comb_threshold(null, harmonic_comb.n_trials(n))
    rng = np.random.default_rng(5)
    above = [0, 0]
    for _ in range(fresh // 1000):
        z = rng.standard_normal((n, 1000))
        z -= basis @ (basis.T @ z)
        above[0] += int(np.sum(best(z) > x))
        above[1] += int(np.sum(harmonic_comb._scores(harmonic_comb._periodogram(z, m), n)[0] > comb_x))
    print(f"| {pname} | {n} | {w.start.size} | {fired[0]} / {fired[1]} of {records} | "
          f"{above[0]} ({100 * above[0] / fresh:.2f} %) / {above[1]} ({100 * above[1] / fresh:.2f} %) of {fresh} |")


def cpu() -> None:
    """Both tests on an effect-free P2-sized record (930,000 samples, 2000 bins), one BLAS thread."""
    with threadpool_limits(limits=1, user_api="blas"):
        for name, test in (("window scan", localized.localized_test), ("harmonic comb", harmonic_comb.comb_test)):
            result, test_s, _resid_s, n = scenarios.timed_residual_test(test, 930_000, 100.0)
            print(f"{name} on {n:,} samples: {test_s:.3f} s CPU (fires: {result.fires})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--group", choices=("unknown", "neighbour", "control"), default="unknown")
    parser.add_argument("--profiles", default="P1,Q1,Q2")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--controls", type=int, default=100)
    parser.add_argument("--cases", default="", help="comma-separated case names (default: the group's all)")
    parser.add_argument("--out", default="")
    parser.add_argument("--table", default="", help="print the Markdown rows of a JSON-lines file and stop")
    parser.add_argument("--null", type=int, default=0, help="the scan alone on this many effect-free refits")
    parser.add_argument("--cpu", action="store_true")
    args = parser.parse_args()
    if args.table:
        return table(args.table)
    if args.cpu:
        return cpu()
    if args.null:
        for pname in args.profiles.split(","):
            null_check(pname, args.null)
        return None
    wanted = set(args.cases.split(",")) if args.cases else None
    with open(args.out or "/dev/stdout", "a", encoding="utf-8") as out:
        for pname, case, seed in jobs(args.group, args.profiles.split(","), args.seeds, args.controls):
            if wanted is None or case in wanted:
                out.write(json.dumps(run(pname, case, seed)) + "\n")
                out.flush()
    return None


if __name__ == "__main__":
    main()
