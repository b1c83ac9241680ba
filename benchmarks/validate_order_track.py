"""The order test (analysis/discrepancy/order_track.py): false alarms, detection, the catalogue, cost.

Cases of our own (not the held-out set's): a bias A·cos(k·θ − φ) locked to the
table angle, at orders and phases of our choosing per profile, sized by its
norm against the white noise over the samples where the table turns (‖s‖/σ
there: in a static hold the line is a constant offset no test can tell from
the bias, so that is the part a size can be read from; ``--whole`` sizes it over
the whole record instead). Effect-free controls through the whole workflow;
effect-free draws of the scan alone on the base refit; catalogue effects at
10σ with the test and without it (``--without``: the hook replaced by the
identity, the workflow as it was before the test).

    .venv/bin/python benchmarks/validate_order_track.py cases --seeds 3
    .venv/bin/python benchmarks/validate_order_track.py controls --profile P1 --draws 100
    .venv/bin/python benchmarks/validate_order_track.py null-scan --profile Q2 --draws 400
    .venv/bin/python benchmarks/validate_order_track.py catalogue [--without]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np  # noqa: E402
import validate_line_drift as drift_bench  # noqa: E402

from gyrocal.analysis.discrepancy import order_track, workflow  # noqa: E402
from gyrocal.analysis.discrepancy.noise_model import NoiseModel  # noqa: E402
from gyrocal.models.indicated import input_history  # noqa: E402

#: (profile, order, phase deg, sizes): our own choices
CASES = [
    ("P1", 24, 30.0, (10.0,)),
    ("Q1", 36, 75.0, (10.0,)),
    ("Q2", 24, 200.0, (10.0, 7.0)),
    ("Q3", 16, 310.0, (10.0,)),
    ("P2", 48, 120.0, (10.0,)),
]
CATALOGUE = ["periodic_interference", "table_angle_harmonic", "sf_nonlinearity_quadratic", "temp_rate_bias",
             "markov_bias"]


def profile(name: str) -> scenarios.Profile:
    return drift_bench.profile(name)


def angle_line(prof: scenarios.Profile, order: int, phase_deg: float, size: float, whole: bool = False
               ) -> np.ndarray:
    """cos(k·θ − φ) (θ the table angle the model integrates), ‖s‖ = size·σ_white over the turning samples."""
    theta = input_history(prof.inputs).angle_deg
    shape = np.cos(np.deg2rad(order * theta - phase_deg))
    part = shape - shape.mean() if whole else shape[np.abs(prof.table_rate_dps) > 0]
    sigma = NoiseModel.of_model(scenarios.nominal_model()).white_sigma_dph(prof.fs_hz)
    return size * sigma * shape / np.linalg.norm(part)


#: one simulated log through the workflow, timed: the drifting-line benchmark's, shared
run = drift_bench.run


def _fired(result) -> bool:
    return result.where.startswith("a line locked to the table angle")


def _claims(result) -> list[tuple[str, float]]:
    return [(f.name, round(f.probability, 2)) for f in result.found]


def cases(seeds: int, whole: bool) -> None:
    for name, order, phase, sizes in CASES:
        prof = profile(name)
        for size in sizes:
            hits = []
            for seed in range(seeds):
                result, cpu = run(prof, 6100 + seed, extra=angle_line(prof, order, phase, size, whole))
                claims = _claims(result)
                hits.append(_fired(result) and result.unexplained and f"order {order} " in result.where
                            and not any(p >= 0.8 for _, p in claims))
                print(f"{name} order {order} {size}σ seed {seed}: unexplained {result.unexplained} claims {claims} "
                      f"cpu {cpu:.1f} s | {result.where[:160]}", flush=True)
            print(f"== {name} order {order} {size}σ: {sum(hits)}/{len(hits)} unexplained with the order named, "
                  "no claim ≥ 0.8", flush=True)


def controls(name: str, draws: int) -> None:
    drift_bench.controls(name, draws, first_seed=8600, fired_by=_fired, what="order line")


def null_scan(name: str, draws: int) -> None:
    """The scan alone on the base refit of effect-free simulated records (noise of the model)."""
    prof = profile(name)
    fired, scores, cpu = 0, [], []
    for seed in range(draws):
        ctx, fit = scenarios.base_refit(prof, 9600 + seed)
        resid = ctx.resid_full(fit)
        start = time.process_time()
        line = order_track.order_scan(resid, ctx.builder.history.angle_deg, ctx.log.table_rate_dps,
                                      ctx.segments.slices, ctx.fs_hz, ctx.noise)
        cpu.append(time.process_time() - start)
        fired += line.fires
        scores.append(line.score)
    print(f"== {name} scan alone, {draws} effect-free draws: fired {fired}; score median {np.median(scores):.2f}, "
          f"max {max(scores):.2f} against {order_track.OrderLine.threshold.fget(line):.2f}; "
          f"{len(ctx.log):,} samples, CPU median {np.median(cpu):.3f} s", flush=True)


def catalogue(seeds: int, profiles: str) -> None:
    for name in profiles.split(","):
        prof = profile(name)
        for effect in CATALOGUE:
            if effect == "markov_bias":
                spec = scenarios.sized_markov(10.0, 30.0, prof)
            else:
                spec = scenarios.sized_effect(effect, 10.0, prof, max_bins=1000)
            for seed in range(seeds):
                result, cpu = run(prof, 6300 + seed, hidden=[spec])
                first = result.found[0].name if result.found else "-"
                print(f"{name} {effect} seed {seed}: first {first} claims {_claims(result)} unexplained "
                      f"{result.unexplained} order {_fired(result)} cpu {cpu:.1f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=["cases", "controls", "null-scan", "catalogue"])
    parser.add_argument("--profile", default="P1")
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--profiles", default="P1,Q2,P2", help="catalogue: the profiles")
    parser.add_argument("--whole", action="store_true", help="size the line over the whole record")
    parser.add_argument("--without", action="store_true", help="the workflow without the order test")
    args = parser.parse_args()
    if args.without:
        workflow.with_order_line = lambda ctx, after, result: result
    if args.mode == "cases":
        cases(args.seeds, args.whole)
    elif args.mode == "controls":
        controls(args.profile, args.draws)
    elif args.mode == "null-scan":
        null_scan(args.profile, args.draws)
    else:
        catalogue(args.seeds, args.profiles)


if __name__ == "__main__":
    main()
