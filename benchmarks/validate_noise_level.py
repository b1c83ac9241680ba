"""The noise-level test (analysis/discrepancy/noise_level.py) alone: false alarms, detection, cost.

Each draw simulates a log on a profile, refits the nominal model (the base
numbers; nothing is searched, so what the test sees is what the workflow's
final refit leaves when nothing is named) and runs the test. Cases:

* ``control``: nothing hidden (the false-alarm rate; ≤ 0.5 % is the budget);
* ``effect``: white noise σ0·(1 + k|ω|) at expected likelihood ratio 10²
  (``tests/support/noise_level_cases.py``; ``--snr`` for another size), the detection rate;
* a catalogue effect at 10σ (or dead_zone 2 deg/s, quantization 1″), *not*
  in the refitted model, so the test sees it raw: it must not fire.

Profiles: P1–P3 (validate_discrepancy.py; on the static P3 only time is a covariate), Q1–Q3 (validate_discrepancy_outside.py),
and two low-rate ones of this benchmark's own (L1: 4 h at 1 Hz, L2: 2 h at 2 Hz,
dwells of 30–40 s between 20–30 deg/s² slews). Prints one row per profile and case
with the CPU time of the test itself. ``--timing N`` instead times the test on a
record of N samples at 250 Hz (the overnight folder's rate).

    .venv/bin/python benchmarks/validate_noise_level.py --profiles Q2,P1 --cases control,effect --draws 100
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import time

import discrepancy_scenarios as scenarios  # noqa: E402
import noise_level_cases as cases  # noqa: E402
from threadpoolctl import threadpool_limits
from validate_discrepancy_outside import PROFILES  # noqa: E402

from gyrocal.analysis.discrepancy.noise_level import noise_level_test
from gyrocal.models.gyro_model import EffectSpec

OWN_PROFILES = {
    "L1": dict(duration_s=14400.0, fs_hz=1.0, setpoints_c=(25.0, 45.0, 0.0), ramps_c_per_min=(1.0, 2.0),
               rates_dps=(1.0, 5.0, 30.0, 100.0), dwell_s=40.0, static_s=300.0, slow_rate_dps=2.0,
               accel_dps2=20.0),
    "L2": dict(duration_s=7200.0, fs_hz=2.0, setpoints_c=(20.0, 50.0), ramps_c_per_min=(0.8,),
               rates_dps=(0.5, 8.0, 60.0), dwell_s=30.0, static_s=200.0, slow_rate_dps=3.0, accel_dps2=30.0),
}


def profile(name: str) -> scenarios.Profile:
    if name == "P1":
        return scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)
    if name == "P2":
        return scenarios.five_temperature_profile()
    if name == "P3":
        return scenarios.static_profile(7200.0, 200.0)
    return scenarios.procedure_profile(**(OWN_PROFILES.get(name) or PROFILES[name][1]))


def hidden_of(case: str, prof: scenarios.Profile) -> list[EffectSpec]:
    if case in ("control", "effect"):
        return []
    if case == "quantization":
        return [EffectSpec("quantization", {"pulse_arcsec": 1.0})]
    if case == "dead_zone":
        return [EffectSpec("dead_zone", {"threshold_dps": 2.0})]
    if case.startswith("markov_bias"):          # markov_bias:τ
        return [scenarios.sized_markov(10.0, float(case.split(":")[1]), prof)]
    return [scenarios.sized_effect(case, 10.0, prof, max_bins=1000)]


def run(pname: str, case: str, draws: int, seed0: int, snr: float = 10.0) -> tuple[int, float]:
    """Fires out of ``draws``, and the test's mean CPU seconds."""
    prof = profile(pname)
    k = cases.sized_noise_growth(snr, prof) if case == "effect" else 0.0
    hidden = hidden_of(case, prof)
    fires, cpu = 0, 0.0
    for seed in range(seed0, seed0 + draws):
        extra = cases.noise_growth_dph(k, prof, seed) if case == "effect" else None
        model = scenarios.nominal_model()
        if case == "quantization":              # the workflow names it from the output lattice first
            model = model.with_effect(hidden[0])
        ctx, after = scenarios.base_refit(prof, seed, hidden, extra, model=model)
        start = time.process_time()
        fires += noise_level_test(ctx, after).fires
        cpu += time.process_time() - start
    return fires, cpu / draws


def timing(n_samples: int) -> None:
    fs = 250.0
    level, test_s, resid_s, n = scenarios.timed_residual_test(noise_level_test, n_samples, fs)
    print(f"{n:,} samples at {fs:g} Hz: the test {test_s:.2f} CPU-s "
          f"(after the full-rate residual, {resid_s:.2f} s), {level.windows} windows, fires {level.fires}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profiles", default="P1,Q1,Q2,Q3,L1,L2")
    parser.add_argument("--cases", default="control,effect")
    parser.add_argument("--draws", type=int, default=100)
    parser.add_argument("--seed", type=int, default=8000)
    parser.add_argument("--snr", type=float, default=10.0, help="size of the growth (expected LR snr²)")
    parser.add_argument("--timing", type=int, default=0, help="time the test on a record of N samples")
    args = parser.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        if args.timing:
            timing(args.timing)
            return
        print("| profile | case | draws | fired | CPU per test (s) |\n|---|---|---|---|---|")
        for pname in args.profiles.split(","):
            for case in args.cases.split(","):
                fires, cpu = run(pname, case, args.draws, args.seed, args.snr)
                print(f"| {pname} | {case} | {args.draws} | {fires} | {cpu:.3f} |", flush=True)


if __name__ == "__main__":
    main()
