"""Fresh held-out validation of the discrepancy workflow against issue 29's Done-when targets.

Every profile and out-of-catalogue shape of ``validate_discrepancy_outside.py``
has been looked at while the workflow was changed, so that set no longer
validates. This one (``tests/support/discrepancy_fresh.py``: profiles R1–R3,
13 out-of-catalogue cases) was made apart from the work on the workflow and is
meant to be run against it, not tuned on. Measures, with Wilson 95 % intervals:

* every catalogue effect the profile can show, at 10σ, named first (and at 5σ
  on the ``--near-profiles``, near the threshold, for the own-gap target);
* effect-free controls: any claim;
* the unknowns: `unexplained`, wrong claims (any, at ≥ 0.8);
* the reliability of the stated probabilities over every claim of this set;
* each named effect's own gap: before ≥ 2× floor, after ≤ 1.5× floor.

Writes its section into docs/discrepancy-validation.md between its markers
(``validate_discrepancy.py`` keeps the section when it regenerates the rest).
One run costs about 4 CPU-s on R1 (960 k samples) and about 1 CPU-s on R2 and
R3 (43 k samples); the defaults (430 runs) take about 14 CPU-min, about 8 min wall on 2 idle cores.

    .venv/bin/python benchmarks/validate_discrepancy_fresh.py --workers 2
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
import argparse
import time
from concurrent.futures import ProcessPoolExecutor

import discrepancy_fresh as fresh  # noqa: E402
import discrepancy_validation_tables as tables  # noqa: E402
import numpy as np
from discrepancy_cases import Case  # noqa: E402

BEGIN, END = "<!-- fresh-held-out:begin -->", "<!-- fresh-held-out:end -->"
DEFAULT_CONTROLS = "R1:16,R2:42,R3:42"


def run_case(case: Case) -> tables.Outcome:
    return tables.analyse_case(case, fresh.profile(case.profile), fresh.case_extra_dph(case))


def parse_counts(text: str, profiles: list[str]) -> dict[str, int]:
    """"R1:16,R2:42" (or one number for every profile) → runs per profile."""
    if ":" not in text:
        return dict.fromkeys(profiles, int(text))
    counts = {}
    for item in text.split(","):
        name, _, count = item.partition(":")
        if name.strip() not in fresh.PROFILES:
            raise SystemExit(f"--controls: unknown profile {name.strip()!r} in {text!r}")
        counts[name.strip()] = int(count)
    return {p: counts.get(p, 0) for p in profiles}


def build_cases(args) -> list[Case]:
    profiles = args.profiles.split(",")
    controls = parse_counts(args.controls, profiles)
    near = set(args.near_profiles.split(",")) if args.near_profiles else set()
    cases: list[Case] = []
    for p in profiles:
        cases += fresh.fresh_cases(args.seeds, controls[p], args.unknown_seeds, profiles=(p,),
                                   near_seeds=args.near_seeds if p in near else 0)
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4, help="runs per catalogue effect and profile")
    parser.add_argument("--unknown-seeds", type=int, default=3, help="runs per unknown and profile")
    parser.add_argument("--controls", default=DEFAULT_CONTROLS, help="effect-free runs per profile")
    parser.add_argument("--near-seeds", type=int, default=2, help="runs per effect at 5σ")
    parser.add_argument("--near-profiles", default="R2", help="profiles with the 5σ rows")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--profiles", default="R1,R2,R3")
    parser.add_argument("--out", default="docs/discrepancy-validation.md")
    args = parser.parse_args()
    start = time.perf_counter()
    cases = build_cases(args)
    print(f"{len(cases)} runs on {args.workers} worker(s)", file=sys.stderr)
    with ProcessPoolExecutor(args.workers) as pool:
        outcomes = list(pool.map(run_case, cases))
    section = _section(outcomes, args, time.perf_counter() - start)
    tables.write_section(Path(args.out), BEGIN, END, section)
    print(section)


def _command(args) -> str:
    near = args.near_profiles or "''"
    return (f"    .venv/bin/python benchmarks/validate_discrepancy_fresh.py --seeds {args.seeds} "
            f"--unknown-seeds {args.unknown_seeds} --controls {args.controls} --near-seeds {args.near_seeds} "
            f"--near-profiles {near} --profiles {args.profiles} --workers {args.workers}")


def _set_description(args) -> list[str]:
    lines = ["Profiles (unlike P1–P3 and Q1–Q3: new sample rates, durations and temperature paths):", ""]
    for p in args.profiles.split(","):
        prof = fresh.PROFILES[p]
        left_out = (f"; not sized there: {', '.join(prof.unobservable)} (nothing for it to act on)"
                    if prof.unobservable else "")
        left_out += (f"; unknowns not run there (catalogue effects on this path): {', '.join(prof.catalogue_alike)}"
                     if prof.catalogue_alike else "")
        lines.append(f"- **{prof.title}**: dead zone {prof.dead_zone_dps:g} deg/s, Markov τ "
                     f"{' and '.join(f'{t:g}' for t in prof.markov_taus_s)} s, pulse {prof.pulse_arcsec:g}″"
                     f"{left_out}")
    sizing = {"bins": "known-shape SNR of its binned shape", "white": "norm against the white noise",
              "noise": "expected likelihood ratio of the variance change"}
    lines += ["", "Structure outside the catalogue (each at 10σ, with its sizing):", ""]
    lines += [f"- {name} ({sizing[u.sizing]}" + (f"; beside {u.with_effect} at 10σ" if u.with_effect else "")
              + ")" for name, u in fresh.UNKNOWN.items()]
    lines += ["", "What is held out: this set was made apart from the work on the workflow and no run of it "
              "was read before the run below (one small smoke run checked only that the runner works). "
              "A claim is right when the named effect was hidden; on a control or a lone unknown every "
              "claim is wrong. Rates carry Wilson 95 % intervals in brackets.", ""]
    return lines


def _targets(outcomes: list[tables.Outcome]) -> list[str]:
    lines = ["| issue 29 Done-when item | measured [Wilson 95 %] | holds? |", "|---|---|---|"]
    for name, figure in zip(tables.TARGET_NAMES, tables.targets(outcomes, interval=True), strict=True):
        holds = "–" if figure.holds is None else ("yes" if figure.holds else "**no**")
        lines.append(f"| {name} | {figure.text} | {holds} |")
    lines.append("| overnight folder still ≤ 30 s | not measured here: "
                 "`benchmarks/bench_discrepancy_overnight.py --repeat 3` on an idle machine | – |")
    return lines


def _separability(profiles: list[str]) -> list[str]:
    """Per profile: each effect's and unknown's closest single catalogue effect, and the SNR it leaves.

    A property of the set, computed without the workflow (``fresh.snr_space``):
    an effect that leaves little beside its closest look-alike cannot be named
    first reliably by any method at 10σ; an unknown that leaves little beside a
    catalogue effect is nearly that effect on this profile.
    """
    lines = ["| profile | hidden (10σ) | closest other catalogue effect | SNR left after it |",
             "|---|---|---|---|"]
    for p in profiles:
        for name in fresh.catalogue_columns(p):
            closest, left = fresh.closest_catalogue(p, fresh.effect_signature(p, name), leave_out=name)
            lines.append(f"| {p} | {name} | {closest} | {left:.1f} |")
        for name, unknown in fresh.UNKNOWN.items():
            if unknown.sizing != "bins" or unknown.with_effect:
                continue
            signal = fresh.snr_space(p).project(fresh.extra_dph(name, fresh.profile(p), 10.0, 9500))
            closest, left = fresh.closest_catalogue(p, signal)
            skipped = " (not run here: a catalogue effect on this profile)" if name in fresh.PROFILES[p].catalogue_alike else ""
            lines.append(f"| {p} | {tables.cell(name)} (seed 9500){skipped} | {closest} | {left:.1f} |")
    return lines


def _section(outcomes: list[tables.Outcome], args, elapsed: float) -> str:
    rows = tables.by_label(outcomes)
    lines = ["## Fresh held-out set: profiles R1–R3, new structure outside the catalogue (issue 29)", "",
             "Regenerate with", "", _command(args), ""]
    lines += _set_description(args)
    lines += ["### What the profiles can tell apart", "",
              "Whitened, base-projected binned signatures at 10σ (norm 10), before any analysis: the SNR "
              "left once the closest single catalogue effect is fitted to them (thermal_lag's column at "
              f"τ {fresh.LAG_COLUMN_TAU_S:g} s). sf_nonlinearity_quadratic "
              "and sf_asymmetry (ω² against |ω|) stay close on any rate ladder.", ""]
    lines += _separability(args.profiles.split(","))
    lines += ["", "### Catalogue effects", ""] + tables.effect_rows(rows, interval=True)
    lines += ["", "### Controls and unknowns", ""] + tables.other_rows(rows, interval=True)
    lines += ["", "### Against the targets", ""] + _targets(outcomes)
    lines += ["", "### Reliability of the stated probabilities (this set only)", "",
              "All claims of the set:", ""] + tables.reliability_rows(outcomes, interval=True)
    lines += ["", "Claims on controls and unknowns only:", ""]
    lines += tables.reliability_rows([o for o in outcomes if o.case.group != "effect"], interval=True)
    per_profile = ", ".join(f"{p} {np.median([o.cpu_seconds for o in outcomes if o.case.profile == p]):.1f}"
                            for p in args.profiles.split(","))
    cpu_min = sum(o.cpu_seconds for o in outcomes) / 60
    lines += ["", f"{len(outcomes)} runs, {elapsed / 60:.1f} min wall on {args.workers} worker(s), "
              f"{cpu_min:.1f} CPU-min in the runs (median CPU s per run: {per_profile}).", ""]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
