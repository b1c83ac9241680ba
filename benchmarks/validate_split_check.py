"""The split check (analysis/discrepancy/split_check.py): own out-of-catalogue cases, catalogue, controls.

Every case here is our own (profiles, shapes, parameters): the held-out sets R and S
only said which *kinds* of structure drew a catalogue name (a temperature step of the
scale factor, a dT/dt law changing with temperature, a switching bias, ...). Each run
goes through the whole workflow once; "before" is the same run with the split check's
verdict left out (its input recorded: the named effects and whether anything else made
the result unexplained), "after" the result as the workflow returns it.

    .venv/bin/python benchmarks/validate_split_check.py unknowns --seeds 41,42,43
    .venv/bin/python benchmarks/validate_split_check.py catalogue --seeds 41,42
    .venv/bin/python benchmarks/validate_split_check.py controls --seeds 1-20
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np  # noqa: E402
from discrepancy_validation_tables import wilson  # noqa: E402

from gyrocal.analysis.discrepancy import workflow  # noqa: E402
from gyrocal.analysis.discrepancy.segments import temperature_trend_c_per_min  # noqa: E402

MAX_BINS = 1000


def profile_q1() -> scenarios.Profile:
    """Q1 of validate_discrepancy_outside.py (1.5 h, 20 Hz, 20 → 50 → 0 → 30 °C)."""
    return scenarios.procedure_profile(5400.0, 20.0, setpoints_c=(20.0, 50.0, 0.0, 30.0),
                                       ramps_c_per_min=(1.5, 4.0, 2.5), rates_dps=(1.0, 5.0, 30.0, 150.0),
                                       dwell_s=25.0, static_s=100.0, slow_rate_dps=5.0, accel_dps2=20.0)


def profile_u1() -> scenarios.Profile:
    """Own: 2 h, 8 Hz, 30 → 10 → 48 → 22 °C at 1.2, 2, 3 °C/min, ±2…120 deg/s at 40 deg/s²."""
    return scenarios.procedure_profile(7200.0, 8.0, setpoints_c=(30.0, 10.0, 48.0, 22.0),
                                       ramps_c_per_min=(1.2, 2.0, 3.0), rates_dps=(2.0, 15.0, 120.0),
                                       dwell_s=30.0, static_s=120.0, slow_rate_dps=4.0, accel_dps2=40.0)


def profile_u2() -> scenarios.Profile:
    """Own: 3 h, 10 Hz, seven soaks 25 → 5 → 15 → 35 → 45 → 55 → 30 °C at 2 °C/min, ±1…90 deg/s."""
    return scenarios.procedure_profile(10800.0, 10.0, setpoints_c=(25.0, 5.0, 15.0, 35.0, 45.0, 55.0, 30.0),
                                       ramps_c_per_min=(2.0,) * 6, rates_dps=(1.0, 12.0, 90.0), dwell_s=20.0,
                                       static_s=60.0, slow_rate_dps=6.0, accel_dps2=30.0)


PROFILES = {"Q1": profile_q1, "U1": profile_u1, "U2": profile_u2}


def _dtdt(p: scenarios.Profile) -> np.ndarray:
    return temperature_trend_c_per_min(p.t_s, p.chamber_temp_c)


def _telegraph(p: scenarios.Profile, seed: int, dwell_s: float = 450.0) -> np.ndarray:
    rng = np.random.default_rng(seed + 777)
    out, level, now = np.zeros_like(p.t_s), 1.0, 0.0
    while now < p.t_s[-1]:
        nxt = now + rng.exponential(dwell_s)
        out[(p.t_s >= now) & (p.t_s < nxt)] = level
        level, now = -level, nxt
    return out


def _redrawn(p: scenarios.Profile, seed: int) -> np.ndarray:
    levels = np.random.default_rng(seed + 991).standard_normal(4)
    edges = np.array([0.0, 0.22, 0.51, 0.78, 1.01]) * p.t_s[-1]
    return (levels - levels.mean())[np.searchsorted(edges, p.t_s, side="right") - 1]


def _settling(p: scenarios.Profile, tau_s: float) -> np.ndarray:
    change = np.r_[True, np.abs(np.diff(p.table_rate_dps)) > 1e-9]
    last = np.maximum.accumulate(np.where(change, p.t_s, -np.inf))
    return p.table_rate_dps * np.exp(-(p.t_s - last) / tau_s)


def _since_path_change(p: scenarios.Profile, scale_s: float) -> np.ndarray:
    slope = np.round(_dtdt(p), 1)
    last = np.maximum.accumulate(np.where(np.r_[True, np.diff(slope) != 0], p.t_s, -np.inf))
    return np.log1p((p.t_s - last) / scale_s)


#: out-of-catalogue shapes (per sample, deg/h before sizing), our own parameters
FAMILIES = {
    "SF step above 36 °C": lambda p, s: np.where(p.chamber_temp_c > 36.0, p.table_rate_dps, 0.0),
    "bias in dT/dt·(T − 15 °C)": lambda p, s: _dtdt(p) * (p.chamber_temp_c - 15.0),
    "bias in dT/dt above 30 °C only": lambda p, s: _dtdt(p) * (p.chamber_temp_c > 30.0),
    "bias in ΔT while heating only": lambda p, s: (p.chamber_temp_c - 25.0) * (_dtdt(p) > 0.05),
    "telegraph bias (mean dwell 450 s)": _telegraph,
    "bias redrawn at 3 power cycles": _redrawn,
    "|ω|^1.5 on negative rates only": lambda p, s: np.where(p.table_rate_dps < 0,
                                                             np.abs(p.table_rate_dps) ** 1.5, 0.0),
    "bias ∝ table angular acceleration": lambda p, s: np.gradient(p.table_rate_dps, p.t_s),
    "SF settling after rate changes (τ 6 s)": lambda p, s: _settling(p, 6.0),
    "bias in log(1 + time since the temperature path changed / 90 s)": lambda p, s: _since_path_change(p, 90.0),
}
CATALOGUE = ["thermal_lag", "temp_rate_bias", "temp_hysteresis", "bias_temp_quadratic", "sf_temp_quadratic",
             "sf_nonlinearity_quadratic", "sf_nonlinearity_cubic", "sf_asymmetry", "warmup_transient",
             "bias_ramp", "table_angle_harmonic"]


@dataclass
class Run:
    profile: str
    case: str
    seed: int
    before: list[tuple[str, float]]
    unexplained_before: bool
    after: list[tuple[str, float]]
    unexplained: bool
    cpu_s: float


_SEEN: dict = {}
_original_check = workflow.split_check


def _recording_check(ctx, after, found):
    check = _original_check(ctx, after, found)
    _SEEN.update(check=check, found=[(f.name, f.probability) for f in found])
    return check


workflow.split_check = _recording_check


def run(profile: str, case: str, seed: int) -> Run:
    p = PROFILES[profile]()
    extra, hidden = None, []
    if case in FAMILIES:
        extra = scenarios.sized_extra(FAMILIES[case](p, seed), 10.0, p, max_bins=MAX_BINS)
    elif case == "markov_bias":
        hidden = [scenarios.sized_markov(10.0, 200.0, p)]
    elif case != "control":
        hidden = [scenarios.sized_effect(case, 10.0, p, max_bins=MAX_BINS)]
    start = time.process_time()
    result = scenarios.analyse_scenario(p, hidden, seed, max_bins=MAX_BINS, n_null=300, extra_dph=extra)
    check = _SEEN["check"]
    # unexplained for another reason: where holds more than the split check's own description
    other = result.unexplained and not (check.fires and result.where == check.describe())
    return Run(profile, case, seed, _SEEN["found"], other, [(f.name, f.probability) for f in result.found],
               result.unexplained, time.process_time() - start)


def _rate(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"{k}/{n} = {100 * k / n:.0f} % [{100 * lo:.0f}–{100 * hi:.0f}]" if n else "–"


def summary(runs: list[Run], mode: str) -> None:
    n = len(runs)
    if mode == "catalogue":
        for label, key in (("before", "before"), ("after", "after")):
            first = sum(bool(getattr(r, key)) and getattr(r, key)[0][0] == r.case for r in runs)
            print(f"10σ named first, {label}: {_rate(first, n)}")
        return
    for label, found, unexplained in (("before", "before", "unexplained_before"), ("after", "after", "unexplained")):
        wrong = sum(any(pr >= 0.8 for _, pr in getattr(r, found)) for r in runs)
        unexp = sum(getattr(r, unexplained) for r in runs)
        print(f"{label}: unexplained {_rate(unexp, n)}; a claim ≥ 0.8 {_rate(wrong, n)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("unknowns", "catalogue", "controls"))
    parser.add_argument("--seeds", default="41,42")
    parser.add_argument("--profiles", default="Q1,U1,U2")
    args = parser.parse_args()
    if "-" in args.seeds:
        lo, hi = (int(v) for v in args.seeds.split("-"))
        seeds = list(range(lo, hi + 1))
    else:
        seeds = [int(v) for v in args.seeds.split(",")]
    cases = {"unknowns": list(FAMILIES), "catalogue": [*CATALOGUE, "markov_bias"], "controls": ["control"]}
    runs = []
    for profile in args.profiles.split(","):
        for case in cases[args.mode]:
            for seed in seeds:
                r = run(profile, case, seed)
                runs.append(r)
                print(f"{r.profile} | {r.case} | {r.seed} | before {[(k, round(v, 2)) for k, v in r.before]} "
                      f"unexplained {r.unexplained_before} | after {[(k, round(v, 2)) for k, v in r.after]} "
                      f"unexplained {r.unexplained} | {r.cpu_s:.1f} s CPU", flush=True)
    summary(runs, args.mode)


if __name__ == "__main__":
    main()
