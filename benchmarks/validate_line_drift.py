"""The drifting-line test (analysis/discrepancy/line_drift.py): false alarms, detection, cost.

Cases of our own (not the held-out set's): a periodic line whose frequency moves
with temperature or time, sized by its norm against the white noise (‖s‖/σ, the
coherent Δχ² is its square), on the P and Q profiles; effect-free controls
through the whole workflow; effect-free draws of the scan alone on a P2-sized
record; the catalogue's periodic_interference and table_angle_harmonic at 10σ
with the test and without it (``--without``: the hook replaced by "nothing
found", the workflow as it was before the test).

    .venv/bin/python benchmarks/validate_line_drift.py cases
    .venv/bin/python benchmarks/validate_line_drift.py controls --profile P1 --draws 100
    .venv/bin/python benchmarks/validate_line_drift.py null-scan --draws 100
    .venv/bin/python benchmarks/validate_line_drift.py catalogue [--without]
    .venv/bin/python benchmarks/validate_line_drift.py cpu
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
import validate_discrepancy as inside  # noqa: E402
import validate_discrepancy_outside as outside  # noqa: E402

from gyrocal.analysis.discrepancy import line_drift, workflow  # noqa: E402
from gyrocal.analysis.discrepancy.noise_model import NoiseModel  # noqa: E402
from gyrocal.analysis.discrepancy.segments import make_bins  # noqa: E402
from gyrocal.analysis.discrepancy.signatures import DesignBuilder  # noqa: E402
from gyrocal.models.rate_units import output_to_dph  # noqa: E402

#: (profile, frequency Hz, relative drift per unit, covariate, sizes): our own choices
CASES = [
    ("P1", 1.7, 0.0015, "temperature", (10.0, 15.0)),
    ("Q1", 4.1, -0.0008, "temperature", (10.0, 15.0)),
    ("Q2", 11.3, 0.0012, "temperature", (10.0, 15.0)),
    ("Q3", 2.2, 0.002, "temperature", (10.0,)),
    ("P2", 23.5, -0.0005, "temperature", (10.0, 15.0, 20.0)),
    ("P3", 37.0, 0.002 / 3600.0, "time", (10.0, 15.0)),
]


def profile(name: str) -> scenarios.Profile:
    """P1–P3 as validate_discrepancy.py builds them, Q1–Q3 as validate_discrepancy_outside.py."""
    return inside.profile(name) if name.startswith("P") else outside.profile(name)


def drifting_shape(prof: scenarios.Profile, freq_hz: float, drift: float, covariate: str, size: float
                   ) -> np.ndarray:
    """sin of the phase 2π∫f·(1 + c·(x − x̄))dt, scaled to ‖s‖ = size·σ_white (deg/h)."""
    x = prof.chamber_temp_c if covariate == "temperature" else prof.t_s
    phase = 2.0 * np.pi * np.cumsum(freq_hz * (1.0 + drift * (x - x.mean()))) / prof.fs_hz
    shape = np.sin(phase + 0.7)
    sigma = NoiseModel.of_model(scenarios.nominal_model()).white_sigma_dph(prof.fs_hz)
    return size * sigma * shape / np.linalg.norm(shape)


def run(prof: scenarios.Profile, seed: int, hidden=(), extra: np.ndarray | None = None):
    samples = scenarios.simulate_log(prof, list(hidden), seed, extra_dph=extra)
    cpu = time.process_time()
    result = workflow.analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                              n_null=300, max_bins=1000)
    return result, time.process_time() - cpu


def _line(result) -> bool:
    return result.where.startswith("a periodic line near")


def cases(seeds: int) -> None:
    for name, freq, drift, covariate, sizes in CASES:
        prof = profile(name)
        for size in sizes:
            hits = []
            for seed in range(seeds):
                result, cpu = run(prof, 7100 + seed, extra=drifting_shape(prof, freq, drift, covariate, size))
                claims = [(f.name, round(f.probability, 2)) for f in result.found]
                hits.append(_line(result) and result.unexplained
                            and not any(p >= 0.8 for _, p in claims))
                print(f"{name} {freq} Hz {drift:+.3g}/{covariate} {size}σ seed {seed}: unexplained "
                      f"{result.unexplained} claims {claims} cpu {cpu:.1f} s | {result.where[:140]}", flush=True)
            print(f"== {name} {size}σ: {sum(hits)}/{len(hits)} unexplained with the line named, no claim ≥ 0.8",
                  flush=True)


def controls(name: str, draws: int, first_seed: int = 8300, fired_by=None, what: str = "drifting line") -> None:
    """Effect-free draws of profile ``name``: how often ``fired_by`` (the test's own report) fired,
    how often anything was claimed or called unexplained. Shared with the order test's benchmark."""
    fired_by = fired_by or _line
    prof = profile(name)
    fired = claims = unexplained = 0
    for seed in range(draws):
        result, _ = run(prof, first_seed + seed)
        fired += fired_by(result)
        claims += bool(result.found)
        unexplained += result.unexplained
        if fired_by(result):
            print(f"seed {seed}: {result.where[:200]}", flush=True)
    print(f"== {name} controls: {what} reported {fired}/{draws}; any claim {claims}/{draws}; "
          f"unexplained {unexplained}/{draws}", flush=True)


def null_scan(draws: int) -> None:
    """The scan alone on effect-free simulated records of P2 (2.6 h at 100 Hz), noise of the model."""
    prof = profile("P2")
    noise = NoiseModel.of_model(scenarios.nominal_model())
    covariates = {"temperature": prof.chamber_temp_c, "time": prof.t_s}
    model = scenarios.nominal_model()
    builder = DesignBuilder(prof.inputs, make_bins(prof.t_s, prof.fs_hz, max_bins=1000))
    truth_dph = builder.rate_dph(model)
    scores, fired, cpu = [], 0, []
    for seed in range(draws):
        samples = scenarios.simulate_log(prof, [], 9100 + seed, base_offset=False)
        resid = output_to_dph(samples.gyro, model.scale_factor) - truth_dph
        start = time.process_time()
        line = line_drift.drift_scan(resid - resid.mean(), prof.fs_hz, noise, 0.1, covariates)
        cpu.append(time.process_time() - start)
        scores.append(line.score)
        fired += line.drifting
    print(f"== null scan P2: drifting {fired}/{draws}, present {sum(s > 2.3 for s in scores)}/{draws}; "
          f"score median {np.median(scores):.2f} max {max(scores):.2f}; cpu median {np.median(cpu):.2f} s")


def catalogue(seeds: int, without: bool) -> None:
    if without:
        line_drift_hook = workflow.drifting_line
        workflow.drifting_line = lambda ctx, after, found: (found, None)
    for name in ("P1", "Q1", "P2"):
        prof = profile(name)
        for effect in ("periodic_interference", "table_angle_harmonic"):
            for seed in range(seeds):
                spec = scenarios.sized_effect(effect, 10.0, prof, max_bins=1000)
                result, cpu = run(prof, 7500 + seed, hidden=[spec])
                first = result.found[0].name if result.found else None
                print(f"{'without' if without else 'with'} {name} {effect} seed {seed}: first {first} "
                      f"claims {[(f.name, round(f.probability, 2)) for f in result.found]} unexplained "
                      f"{result.unexplained} cpu {cpu:.1f} s", flush=True)
    if without:
        workflow.drifting_line = line_drift_hook


def cpu() -> None:
    """CPU of the test on a P2-sized record (930,000 samples), beside the whole workflow's."""
    prof = profile("P2")
    for seed in range(3):
        samples = scenarios.simulate_log(prof, [], 9900 + seed)
        spent = []
        hook = workflow.drifting_line

        def timed(ctx, after, found, hook=hook, spent=spent):
            start = time.process_time()
            out = hook(ctx, after, found)
            spent.append(time.process_time() - start)
            return out

        workflow.drifting_line = timed
        start = time.process_time()
        workflow.analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                         n_null=300, max_bins=1000)
        workflow.drifting_line = hook
        print(f"P2 seed {seed}: drifting-line test {spent[0]:.2f} s CPU of {time.process_time() - start:.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("cases", "controls", "null-scan", "catalogue", "cpu"))
    parser.add_argument("--profile", default="P1")
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--without", action="store_true")
    args = parser.parse_args()
    if args.what == "cases":
        cases(args.seeds)
    elif args.what == "controls":
        controls(args.profile, args.draws)
    elif args.what == "null-scan":
        null_scan(args.draws)
    elif args.what == "catalogue":
        catalogue(args.seeds, args.without)
    else:
        cpu()


if __name__ == "__main__":
    main()
