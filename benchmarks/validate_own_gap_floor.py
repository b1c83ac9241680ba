"""Each named effect's own gap against its floor, on P1 and Q1–Q3 (issue 29: the floor as a stated level).

Runs catalogue effects at 10σ and 5σ (near their test threshold), dead zones, pulse
quantization and Markov biases on the tuning profile P1 and the off-tuning profiles
Q1–Q3 (never the held-out R set), plus effect-free controls, and reports per row:
how often the named effect's headline metric starts at ≥ 2× its floor and ends at
≤ 1.5× its floor, and for the controls any claim and ``unexplained``. Writes every
run's metrics as JSON lines so two versions of the workflow can be compared run by run.

    .venv/bin/python benchmarks/validate_own_gap_floor.py --seeds 4 --out /tmp/own-gap.jsonl
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np
import validate_discrepancy as tuned  # noqa: E402
import validate_discrepancy_outside as outside  # noqa: E402

from gyrocal.analysis.discrepancy.workflow import analyse
from gyrocal.models.gyro_model import EffectSpec

SAMPLE = ["thermal_lag", "temp_rate_bias", "sf_nonlinearity_cubic", "bias_ramp", "sf_asymmetry"]
DEAD_ZONES = {"P1": (2.5, 6.0), "Q1": (2.5,), "Q2": (1.0,), "Q3": (5.0,)}
PULSES = {"P1": (0.5, 2.0), "Q1": (1.0,), "Q2": (1.0,), "Q3": (1.0,)}
MARKOV_TAUS_S = {"P1": (10.0, 100.0), "Q1": (30.0, 300.0), "Q2": (30.0, 300.0), "Q3": (30.0,)}


def profile(name: str) -> scenarios.Profile:
    return tuned.profile(name) if name.startswith("P") else outside.profile(name)


def cases(seeds: int, controls: int, profiles: list[str]) -> list[tuple[str, str, list[EffectSpec], int]]:
    """(profile, label, hidden effects, seed) for every run."""
    out = []
    for pname in profiles:
        prof = profile(pname)
        for snr in (10.0, 5.0):
            for name in SAMPLE:
                spec = scenarios.sized_effect(name, snr, prof, max_bins=1000)
                out += [(pname, f"{name} ({snr:g}σ)", [spec], 8000 + s) for s in range(seeds)]
            for tau in MARKOV_TAUS_S[pname]:
                spec = scenarios.sized_markov(snr, tau, prof)
                out += [(pname, f"markov_bias τ {tau:g} s ({snr:g}σ)", [spec], 8100 + s) for s in range(seeds)]
        for threshold in DEAD_ZONES[pname]:
            spec = EffectSpec("dead_zone", {"threshold_dps": threshold})
            out += [(pname, f"dead_zone {threshold:g} deg/s", [spec], 8200 + s) for s in range(2 * seeds)]
        for pulse in PULSES[pname]:
            spec = EffectSpec("quantization", {"pulse_arcsec": pulse})
            out += [(pname, f"quantization {pulse:g}″", [spec], 8300 + s) for s in range(2 * seeds)]
        out += [(pname, "control", [], 8400 + s) for s in range(controls)]
    return out


def run(case: tuple[str, str, list[EffectSpec], int]) -> dict:
    pname, label, hidden, seed = case
    start = time.process_time()
    samples = scenarios.simulate_log(profile(pname), hidden, seed)
    result = analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                     n_null=300, max_bins=1000)
    metrics = {k: m.to_json() for k, m in result.metrics.items()}
    return {"profile": pname, "label": label, "seed": seed, "hidden": [h.name for h in hidden],
            "found": [[f.name, f.probability] for f in result.found], "unexplained": result.unexplained,
            "headlines": dict(result.effect_gaps), "metrics": metrics, "cpu_s": time.process_time() - start}


def summary(rows: list[dict]) -> list[str]:
    """One line per (profile, label): runs, named, before ≥ 2× floor, after ≤ 1.5× floor (headline)."""
    lines = ["| profile | case | runs | hidden named | before ≥ 2× floor | after ≤ 1.5× floor | "
             "median after / floor | any claim | unexplained |", "|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["profile"], r["label"]), []).append(r)
    for (pname, label), runs in groups.items():
        named = [r for r in runs if r["hidden"] and r["hidden"][0] in r["headlines"]]
        heads = [r["metrics"][r["headlines"][r["hidden"][0]]] for r in named
                 if r["headlines"][r["hidden"][0]] in r["metrics"]]
        before = [h["before"] >= 2.0 * h["noise_floor"] for h in heads]
        after = [h["after"] <= 1.5 * h["noise_floor"] for h in heads]
        ratio = [h["after"] / h["noise_floor"] for h in heads if h["noise_floor"] > 0]

        def pct(v: list[bool]) -> str:
            return f"{100 * np.mean(v):.0f} %" if v else "–"

        lines.append(f"| {pname} | {label} | {len(runs)} | {len(named)} | {pct(before)} | {pct(after)} | "
                     f"{np.median(ratio) if ratio else float('nan'):.2f} | "
                     f"{pct([bool(r['found']) for r in runs])} | {pct([r['unexplained'] for r in runs])} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--controls", type=int, default=10)
    parser.add_argument("--profiles", default="P1,Q1,Q2,Q3")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    todo = cases(args.seeds, args.controls, args.profiles.split(","))
    with ProcessPoolExecutor(args.workers) as pool, args.out.open("w") as fh:
        rows = []
        for row in pool.map(run, todo):
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            rows.append(row)
    print("\n".join(summary(rows)))


if __name__ == "__main__":
    main()
