"""Confusion between sf_nonlinearity_quadratic (k2·ω²) and sf_asymmetry (∝ |ω|) on own cases.

On a rate ladder the two signatures are close: at 10σ only about 2.7σ of whitened
signature is left once the other is fitted (docs/discrepancy-validation.md, "What
the profiles can tell apart"), so the best possible choice names the true one with
probability Φ(d/2). This tool measures which one the workflow names first, at what
stated probability, how often the runner-up is the true one, and the round-one Δχ²
of both (own profiles P1, P2, Q1–Q3; own seeds; never the held-out sets).

    python benchmarks/quadasym_confusion.py --profiles P1 Q1 --snr 10 --seeds 20 --out /tmp/x.jsonl
    python benchmarks/quadasym_confusion.py --table /tmp/x.jsonl      # the Markdown rows
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

from scipy.stats import norm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import validate_discrepancy as inside  # noqa: E402
import validate_discrepancy_outside as outside  # noqa: E402
from discrepancy_validation_tables import pct  # noqa: E402

from gyrocal.analysis.discrepancy.workflow import analyse  # noqa: E402
from tests.support import discrepancy_scenarios as scenarios  # noqa: E402

PAIR = ("sf_nonlinearity_quadratic", "sf_asymmetry")


def profile(name: str) -> scenarios.Profile:
    return inside.profile(name) if name.startswith("P") else outside.profile(name)


def run(pname: str, effect: str, snr: float, seed: int) -> dict:
    prof = profile(pname)
    extra = None
    if effect in outside.UNKNOWN:      # own out-of-catalogue shapes (Q profiles' list), sized like the rest
        extra, hidden = scenarios.sized_extra(outside.UNKNOWN[effect](prof), snr, prof, max_bins=1000), []
    else:
        hidden = [] if effect == "control" else [scenarios.sized_effect(effect, snr, prof, max_bins=1000)]
    samples = scenarios.simulate_log(prof, hidden, seed, extra_dph=extra)
    start = time.process_time()
    result = analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                     n_null=300, max_bins=1000)
    first = result.iterations[0] if result.iterations else None
    return {
        "profile": pname, "effect": effect, "snr": snr, "seed": seed,
        "found": [[f.name, f.probability] for f in result.found],
        "rivals": [[a.name, a.probability] for a in result.found[0].look_alikes] if result.found else [],
        "unexplained": result.unexplained,
        "dchi2": {n: first.delta_chi2.get(n) for n in PAIR} if first else {},
        "threshold": first.threshold if first else None,
        "cpu_s": time.process_time() - start,
    }


def separation(pname: str, snr: float) -> float:
    """Whitened distance between the two signatures at ``snr`` once the other is fitted (true noise)."""
    return scenarios.pair_separation(profile(pname), PAIR, snr, 1000)


def table(paths: list[Path]) -> str:
    """One row per profile, size and true effect: the optimum Φ(d/2) beside what was named."""
    rows: dict[tuple, list[dict]] = defaultdict(list)
    for path in paths:
        for line in path.read_text().splitlines():
            r = json.loads(line)
            if r["effect"] in PAIR:
                rows[(r["profile"], r["snr"], r["effect"])].append(r)
    out = ["| profile | hidden | d | Φ(d/2) | runs | named first | larger Δχ² of the pair is the truth | "
           "named first = larger Δχ² (when named) | nothing named | claims ≥ 0.99 (right) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for (pname, snr, effect), rs in sorted(rows.items()):
        other = next(n for n in PAIR if n != effect)
        d = separation(pname, snr)
        first = [r["found"][0][0] if r["found"] else None for r in rs]
        ml = [r["dchi2"][effect] > r["dchi2"][other] for r in rs]
        named = [f == max(PAIR, key=lambda n, r=r: r["dchi2"][n]) for f, r in zip(first, rs, strict=True)
                 if f is not None]
        high = [f[0] == effect for r in rs for f in r["found"] if f[1] >= 0.99]
        out.append(f"| {pname} | {effect} ({snr:g}σ) | {d:.2f} | {norm.cdf(d / 2):.2f} | {len(rs)} | "
                   f"{pct([f == effect for f in first], True)} | {pct(ml, True)} | {sum(named)}/{len(named)} | "
                   f"{first.count(None)} | {len(high)} ({sum(high)}) |")
    return "\n".join(out)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--table":
        print(table([Path(p) for p in sys.argv[2:]]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profiles", nargs="+", default=["P1", "Q1"])
    parser.add_argument("--effects", nargs="+", default=list(PAIR))
    parser.add_argument("--snr", type=float, nargs="+", default=[10.0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=29000)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    with args.out.open("a") as fh:
        for pname in args.profiles:
            for snr in args.snr:
                for effect in args.effects:
                    for seed in range(args.first_seed, args.first_seed + args.seeds):
                        fh.write(json.dumps(run(pname, effect, snr, seed)) + "\n")
                        fh.flush()


if __name__ == "__main__":
    main()
