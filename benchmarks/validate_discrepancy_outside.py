"""Validation of the discrepancy workflow off its tuning ground (issue 29).

Profiles unlike the three the workflow was tuned on (``validate_discrepancy.py``):
new sample rates, durations and temperature paths (``PROFILES``), and a set of
structure outside the catalogue (``UNKNOWN``: shapes the catalogue does not
have, several of which no probe has either), each sized to a known-shape SNR
like the catalogue effects. Measures:

* every catalogue effect at 10σ named first (and at 5σ, near the threshold);
* effect-free controls: any claim;
* the unknowns: `unexplained`, and any catalogue claim (every one is wrong);
* the reliability of the stated probabilities over every claim of this set;
* each named effect's own gap (own_gap.py): before ≥ 2× floor, after ≤ 1.5× floor.

Writes its section into docs/discrepancy-validation.md between the markers
(``validate_discrepancy.py`` keeps the section when it regenerates the rest).

    .venv/bin/python benchmarks/validate_discrepancy_outside.py --seeds 5 --controls 25 --workers 1
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
import argparse
import re
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import cache

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np

from gyrocal.analysis.discrepancy.segments import temperature_trend_c_per_min
from gyrocal.analysis.discrepancy.workflow import analyse
from gyrocal.models.gyro_model import EffectSpec

BEGIN, END = "<!-- outside-catalogue:begin -->", "<!-- outside-catalogue:end -->"

#: name → (title, procedure_profile keyword arguments)
PROFILES = {
    "Q1": ("Q1 (1.5 h, 20 Hz, 20 → 50 → 0 → 30 °C, 20 deg/s²)",
           dict(duration_s=5400.0, fs_hz=20.0, setpoints_c=(20.0, 50.0, 0.0, 30.0),
                ramps_c_per_min=(1.5, 4.0, 2.5), rates_dps=(1.0, 5.0, 30.0, 150.0), dwell_s=25.0,
                static_s=100.0, slow_rate_dps=5.0, accel_dps2=20.0)),
    # Q2 soaks at three temperatures: with two (25 and 60 °C, the reference at one of them) every
    # dwell sits at ΔT = 0 or 35 °C, where ΔT² = 35·ΔT and sf_temp_quadratic is the refitted linear
    # SF tempco exactly; what was left of it to "size" was slew timing, named 0 of 2
    "Q2": ("Q2 (45 min, 50 Hz, 25 → 60 → 5 → 25 °C at 5 °C/min, ±0.2…300 deg/s)",
           dict(duration_s=2700.0, fs_hz=50.0, setpoints_c=(25.0, 60.0, 5.0, 25.0),
                ramps_c_per_min=(5.0, 5.0, 5.0),
                rates_dps=(0.2, 3.0, 20.0, 300.0), dwell_s=15.0, static_s=60.0, slow_rate_dps=6.0,
                accel_dps2=50.0)),
    "Q3": ("Q3 (3 h, 10 Hz, cooling first 30 → −20 → 45 → 25 °C, 20-minute Allan hold)",
           dict(duration_s=10800.0, fs_hz=10.0, setpoints_c=(30.0, -20.0, 45.0, 25.0),
                ramps_c_per_min=(1.0, 2.0, 3.0), rates_dps=(0.5, 10.0, 80.0), dwell_s=40.0,
                static_s=150.0, slow_rate_dps=2.0, allan_hold_s=1200.0, accel_dps2=10.0)),
}
SIZED = ["thermal_lag", "temp_rate_bias", "temp_hysteresis", "bias_temp_quadratic",
         "sf_temp_quadratic", "sf_nonlinearity_quadratic", "sf_nonlinearity_cubic",
         "sf_asymmetry", "warmup_transient", "bias_ramp", "table_angle_harmonic",
         "periodic_interference"]
DEAD_ZONE_DPS = {"Q1": 2.5, "Q2": 1.0, "Q3": 5.0}
MARKOV_TAUS_S = (30.0, 300.0)
PULSE_ARCSEC = 1.0
#: out-of-catalogue shapes (per sample, deg/h before sizing); those marked "no probe" no probe has
UNKNOWN = {
    "bias accelerating with time (t³)": lambda p: (p.t_s / p.t_s[-1]) ** 3,
    "bias growing exponentially (e^(4t/T))": lambda p: np.exp(4.0 * p.t_s / p.t_s[-1]),
    "bias ramp in |t − t0| (t0 at 40 %)": lambda p: np.abs(p.t_s - 0.4 * p.t_s[-1]),
    "rate² on positive rates only": lambda p: np.where(p.table_rate_dps > 0, p.table_rate_dps**2, 0.0),
    "rate² on negative rates only": lambda p: np.where(p.table_rate_dps < 0, p.table_rate_dps**2, 0.0),
    "bias step at 37 %": lambda p: (p.t_s >= 0.37 * p.t_s[-1]).astype(float),
    "scale-factor step at 37 %": lambda p: np.where(p.t_s >= 0.37 * p.t_s[-1], p.table_rate_dps, 0.0),
    "bias by rate sign": lambda p: np.sign(p.table_rate_dps),
    "bias in ΔT³": lambda p: (p.chamber_temp_c - 25.0) ** 3,
    "scale factor drifting with time": lambda p: p.table_rate_dps * p.t_s,
    "bias in (dT/dt)² (no probe)": lambda p: temperature_trend_c_per_min(p.t_s, p.chamber_temp_c) ** 2,
    "rate² growing with temperature, ω²·ΔT (no probe)":
        lambda p: p.table_rate_dps**2 * (p.chamber_temp_c - 25.0),
    "bias in √t (no probe)": lambda p: np.sqrt(p.t_s),
}
#: shapes added after the workflow was changed on the results of the ones above (issue 29's second
#: session): never looked at while changing it, so with profile Q3 they are the held-out part
FRESH = {
    "bias in log(1 + t/600 s) (no probe, fresh)": lambda p: np.log1p(p.t_s / 600.0),
    "bias in |ω|·ΔT (no probe, fresh)": lambda p: np.abs(p.table_rate_dps) * (p.chamber_temp_c - 25.0),
    "bias step at 70 % decaying with τ 600 s (no probe, fresh)":
        lambda p: np.where(p.t_s >= 0.7 * p.t_s[-1], np.exp(-(p.t_s - 0.7 * p.t_s[-1]) / 600.0), 0.0),
    "scale factor in ΔT³ (no probe, fresh)": lambda p: p.table_rate_dps * ((p.chamber_temp_c - 25.0) / 10.0) ** 3,
}
UNKNOWN.update(FRESH)
#: the profile no run had seen when the workflow was last changed
HELD_OUT_PROFILES = ("Q3",)


@cache
def profile(name: str) -> scenarios.Profile:
    return scenarios.procedure_profile(**PROFILES[name][1])


@dataclass(frozen=True)
class Case:
    group: str               # "effect", "control", "unknown"
    label: str
    profile: str
    hidden: tuple[EffectSpec, ...]
    seed: int
    unknown: str = ""
    snr: float = 10.0


@dataclass(frozen=True)
class Outcome:
    case: Case
    found: list[tuple[str, float]]
    unexplained: bool
    where: str
    headline: dict[str, tuple[str, float, float, float]]   # effect → (metric, before, after, floor)
    seconds: float
    cpu_seconds: float

    @property
    def held_out(self) -> bool:
        return self.case.profile in HELD_OUT_PROFILES or self.case.unknown in FRESH


def run_case(case: Case) -> Outcome:
    start, cpu = time.perf_counter(), time.process_time()
    prof = profile(case.profile)
    extra = (scenarios.sized_extra(UNKNOWN[case.unknown](prof), case.snr, prof, max_bins=1000)
             if case.unknown else None)
    samples = scenarios.simulate_log(prof, list(case.hidden), case.seed, extra_dph=extra)
    result = analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=case.seed,
                     n_null=300, max_bins=1000)
    heads = {}
    for effect, key in result.effect_gaps.items():
        m = result.metrics.get(key)
        if m is not None:
            heads[effect] = (key, m.before, m.after, m.noise_floor)
    return Outcome(case, [(f.name, f.probability) for f in result.found], result.unexplained,
                   result.where[:160], heads, time.perf_counter() - start, time.process_time() - cpu)


def _cases(seeds: int, controls: int, profiles: list[str]) -> list[Case]:
    cases: list[Case] = []
    for pname in profiles:
        prof = profile(pname)
        sizes = (10.0, 5.0) if pname == profiles[0] else (10.0,)
        for snr in sizes:
            for name in SIZED:
                spec = scenarios.sized_effect(name, snr, prof, max_bins=1000)
                cases += [Case("effect", f"{name} ({snr:g}σ)", pname, (spec,), 7000 + s, snr=snr)
                          for s in range(seeds)]
            for tau in MARKOV_TAUS_S:
                spec = scenarios.sized_markov(snr, tau, prof)
                cases += [Case("effect", f"markov_bias τ {tau:g} s ({snr:g}σ)", pname, (spec,), 7100 + s,
                               snr=snr) for s in range(seeds)]
        spec = EffectSpec("dead_zone", {"threshold_dps": DEAD_ZONE_DPS[pname]})
        cases += [Case("effect", f"dead_zone {DEAD_ZONE_DPS[pname]:g} deg/s", pname, (spec,), 7200 + s)
                  for s in range(seeds)]
        spec = EffectSpec("quantization", {"pulse_arcsec": PULSE_ARCSEC})
        cases += [Case("effect", f"quantization {PULSE_ARCSEC:g}″", pname, (spec,), 7300 + s)
                  for s in range(seeds)]
        cases += [Case("control", "control", pname, (), 7400 + s) for s in range(controls)]
        for kind in UNKNOWN:
            cases += [Case("unknown", kind, pname, (), 7500 + s, kind) for s in range(seeds)]
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--controls", type=int, default=25)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--profiles", default="Q1,Q2,Q3")
    parser.add_argument("--out", default="docs/discrepancy-validation.md")
    parser.add_argument("--only", default="",
                        help="run only the cases whose label matches this regular expression, and the "
                             "controls (a partial run for a change that touches a few rows; write it with "
                             "--out elsewhere, the documented table is the full run)")
    args = parser.parse_args()
    start = time.perf_counter()
    cases = _cases(args.seeds, args.controls, args.profiles.split(","))
    if args.only:
        cases = [c for c in cases if c.group == "control" or re.search(args.only, c.label)]
    with ProcessPoolExecutor(args.workers) as pool:
        outcomes = list(pool.map(run_case, cases, chunksize=2))
    section = _section(outcomes, args, time.perf_counter() - start)
    path = Path(args.out)
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    block = f"{BEGIN}\n{section}{END}\n"
    if BEGIN in text and END in text:
        text = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END) + "\n?", lambda _m: block, text, flags=re.S)
    else:
        text = text.rstrip("\n") + "\n\n" + block
    path.write_text(text, encoding="utf-8")
    print(section)


def _pct(values: list[bool]) -> str:
    return f"{100 * np.mean(values):.0f} %" if values else "–"


def _own_gap_ok(o: Outcome) -> tuple[bool, bool] | None:
    """(before ≥ 2× floor, after ≤ 1.5× floor) of the hidden effect's headline, when it was named."""
    name = o.case.hidden[0].name
    if name not in o.headline:
        return None
    _, before, after, floor = o.headline[name]
    return before >= 2.0 * floor, after <= 1.5 * floor


def _named_first(o: Outcome) -> bool:
    return bool(o.found) and o.found[0][0] == o.case.hidden[0].name


def _targets(outcomes: list[Outcome]) -> list[str]:
    """The issue's Done-when figures on a set of runs (one table column)."""
    by_label: dict[tuple[str, str], list[Outcome]] = {}
    for o in outcomes:
        by_label.setdefault((o.case.profile, o.case.label), []).append(o)
    rows_10 = [[_named_first(o) for o in outs] for outs in by_label.values()
               if outs[0].case.group == "effect" and outs[0].case.snr == 10.0]
    tenth = [o for o in outcomes if o.case.group == "effect" and o.case.snr == 10.0]
    controls = [o for o in outcomes if o.case.group == "control"]
    unknowns = [o for o in outcomes if o.case.group == "unknown"]
    claims = [(pr, n in {h.name for h in o.case.hidden}) for o in outcomes for n, pr in o.found]
    high = [right for pr, right in claims if pr >= 0.99]
    gaps = [g for g in (_own_gap_ok(o) for o in outcomes if o.case.group == "effect") if g is not None]
    worst = min((float(np.mean(r)) for r in rows_10), default=float("nan")) * 100
    return [f"{worst:.0f} % (pooled {_pct([_named_first(o) for o in tenth])} of {len(tenth)})",
            f"{_pct([bool(o.found) for o in controls])} of {len(controls)}",
            f"{_pct(high)} of {len(high)}",
            f"{_pct([o.unexplained for o in unknowns])} of {len(unknowns)}",
            _pct([any(pr >= 0.8 for _, pr in o.found) for o in unknowns]),
            f"{_pct([g[0] for g in gaps])} of {len(gaps)}",
            f"{_pct([g[1] for g in gaps])} of {len(gaps)}"]


def _reliability(outcomes: list[Outcome]) -> list[str]:
    claims = [(pr, n in {h.name for h in o.case.hidden}) for o in outcomes for n, pr in o.found]
    lines = ["| stated probability | claims | mean stated | right |", "|---|---|---|---|"]
    edges = [0.0, 0.5, 0.8, 0.9, 0.95, 0.99, 1.0001]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = [(pr, right) for pr, right in claims if lo <= pr < hi]
        mean = f"{np.mean([pr for pr, _ in inside]):.3f}" if inside else "–"
        lines.append(f"| {lo:.2f} – {min(hi, 1.0):.2f} | {len(inside)} | {mean} | {_pct([r for _, r in inside])} |")
    return lines


def _effect_rows(by_label: dict[tuple[str, str], list[Outcome]]) -> list[str]:
    lines = ["| profile | hidden effect | runs | named first | own gap before ≥ 2× floor | "
             "own gap after ≤ 1.5× floor | median CPU s |", "|---|---|---|---|---|---|---|"]
    for (p, label), outs in by_label.items():
        if outs[0].case.group != "effect":
            continue
        gaps = [g for g in (_own_gap_ok(o) for o in outs) if g is not None]
        lines.append(f"| {p} | {label} | {len(outs)} | {_pct([_named_first(o) for o in outs])} | "
                     f"{_pct([g[0] for g in gaps])} | {_pct([g[1] for g in gaps])} | "
                     f"{np.median([o.cpu_seconds for o in outs]):.1f} |")
    return lines


def _other_rows(by_label: dict[tuple[str, str], list[Outcome]]) -> list[str]:
    lines = ["| profile | case | runs | `unexplained` | any catalogue claim | claims ≥ 0.8 | what was named |",
             "|---|---|---|---|---|---|---|"]
    for (p, label), outs in by_label.items():
        if outs[0].case.group == "effect":
            continue
        names = sorted({n for o in outs for n, _ in o.found})
        lines.append(f"| {p} | {label} | {len(outs)} | {_pct([o.unexplained for o in outs])} | "
                     f"{_pct([bool(o.found) for o in outs])} | "
                     f"{_pct([any(pr >= 0.8 for _, pr in o.found) for o in outs])} | {', '.join(names) or '–'} |")
    return lines


def _section(outcomes: list[Outcome], args, elapsed: float) -> str:
    by_label: dict[tuple[str, str], list[Outcome]] = {}
    for o in outcomes:
        by_label.setdefault((o.case.profile, o.case.label), []).append(o)
    held = [o for o in outcomes if o.held_out]
    lines = ["## Off the tuning ground: new profiles and structure outside the catalogue (issue 29)", "",
             "Regenerate with", "",
             f"    .venv/bin/python benchmarks/validate_discrepancy_outside.py --seeds {args.seeds} "
             f"--controls {args.controls} --profiles {args.profiles} --workers {args.workers}", "",
             "Profiles (none used while the workflow was first tuned, on P1–P3):", ""]
    lines += [f"- **{PROFILES[p][0]}**" for p in args.profiles.split(",")]
    lines += ["", "What is held out: Q1, Q2 and the first 13 out-of-catalogue shapes were run before the "
              "last changes to the workflow (the quantization floor, the temperature-cubic probe's own "
              "quadratic) and their failures motivated them, so they are no longer clean validation. "
              "**Q3 and the shapes marked “fresh” were not looked at before those changes**; the *held out* "
              "column counts only them. (They were run once with a rule that called any probe left "
              "significant after the fit `unexplained`; it was taken out again for its false alarms on Q2 "
              "controls, 2 of 10, not for anything in the held-out runs.)", "",
              "Out-of-catalogue shapes are sized like the catalogue effects (known-shape SNR 10 of the "
              "whitened, base-projected signature, `scenarios.sized_extra`); the ones marked "
              "“no probe” have no matching probe.", "", "### Catalogue effects", ""]
    lines += _effect_rows(by_label)
    lines += ["", "### Controls and unknowns", ""] + _other_rows(by_label)
    names = ["every catalogue effect at 10σ named first ≥ 90 % (worst row)", "effect-free controls with a claim ≤ 2 %",
             "claims at ≥ 0.99 right ≥ 99 %", "unknowns `unexplained` ≥ 90 %",
             "unknowns with a catalogue claim at ≥ 0.8", "named effect's own gap before ≥ 2× floor",
             "named effect's own gap after ≤ 1.5× floor"]
    lines += ["", "### Against the targets", "", "| target | all runs | held out (Q3, fresh shapes) |",
              "|---|---|---|"]
    lines += [f"| {n} | {a} | {h} |" for n, a, h in zip(names, _targets(outcomes), _targets(held), strict=True)]
    lines += ["", "### Reliability of the stated probabilities (this set only)", "",
              "Every claim above, binned by its stated probability; right when the named effect was hidden "
              "(every claim on a control or an unknown is wrong). All runs:", ""] + _reliability(outcomes)
    lines += ["", "Held out only:", ""] + _reliability(held)
    cpu_min = sum(o.cpu_seconds for o in outcomes) / 60
    lines += ["", f"{len(outcomes)} runs, {elapsed / 60:.1f} min wall on {args.workers} worker(s) "
              f"({cpu_min:.1f} CPU-min; the 2-core machine was shared by about 8 people).", ""]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
