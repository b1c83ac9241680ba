"""Running and scoring discrepancy validation cases; the tables of docs/discrepancy-validation.md.

Shared by ``validate_discrepancy_outside.py`` and ``validate_discrepancy_fresh.py``
so that both sets are scored by one rule: a claim is right when the named effect
was hidden (``Case.is_right``), an effect row counts the hidden effect named
first, and each named effect's own gap is judged against its own floor. Rates
carry Wilson 95 % intervals, since most rows hold a handful of runs.
"""

from __future__ import annotations

import sys
from pathlib import Path

# the synthetic scenarios are test material (tests/support), shared with the benchmarks
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
import math
import re
import time
from dataclasses import dataclass

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np
from discrepancy_cases import Case  # noqa: E402

from gyrocal.analysis.discrepancy.workflow import analyse


@dataclass(frozen=True)
class Outcome:
    case: Case
    found: list[tuple[str, float]]
    unexplained: bool
    where: str
    headline: dict[str, tuple[str, float, float, float]]   # effect → (metric, before, after, floor)
    seconds: float
    cpu_seconds: float


def analyse_case(case: Case, prof: scenarios.Profile, extra_dph: np.ndarray | None) -> Outcome:
    """Simulate the case's log (hidden effects + ``extra_dph``) and run the workflow on it, timed."""
    start, cpu = time.perf_counter(), time.process_time()
    samples = scenarios.simulate_log(prof, list(case.hidden), case.seed, extra_dph=extra_dph)
    result = analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=case.seed,
                     n_null=300, max_bins=1000)
    heads = {}
    for effect, key in result.effect_gaps.items():
        m = result.metrics.get(key)
        if m is not None:
            heads[effect] = (key, m.before, m.after, m.noise_floor)
    return Outcome(case, [(f.name, f.probability) for f in result.found], result.unexplained,
                   result.where[:160], heads, time.perf_counter() - start, time.process_time() - cpu)


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of a proportion k/n (95 % for z = 1.96)."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def pct(values: list[bool], interval: bool = False) -> str:
    """"x %" of the true values (with the Wilson 95 % interval when asked); "–" for none."""
    if not values:
        return "–"
    text = f"{100 * np.mean(values):.0f} %"
    if interval:
        lo, hi = wilson(int(sum(values)), len(values))
        text += f" [{100 * lo:.0f}–{100 * hi:.0f}]"
    return text


def cell(text: str) -> str:
    """Text for a Markdown table cell: a "|" (as in |ω|) escaped so it does not split the cell."""
    return text.replace("|", "\\|")


def by_label(outcomes: list[Outcome]) -> dict[tuple[str, str], list[Outcome]]:
    rows: dict[tuple[str, str], list[Outcome]] = {}
    for o in outcomes:
        rows.setdefault((o.case.profile, o.case.label), []).append(o)
    return rows


def named_first(o: Outcome) -> bool:
    return bool(o.found) and o.found[0][0] == o.case.hidden[0].name


def own_gap_ok(o: Outcome) -> tuple[bool, bool] | None:
    """(before ≥ 2× floor, after ≤ 1.5× floor) of the hidden effect's headline, when it was named."""
    name = o.case.hidden[0].name
    if name not in o.headline:
        return None
    _, before, after, floor = o.headline[name]
    return before >= 2.0 * floor, after <= 1.5 * floor


def claims(outcomes: list[Outcome]) -> list[tuple[float, bool]]:
    """Every claim of every run: (stated probability, right)."""
    return [(pr, o.case.is_right(n)) for o in outcomes for n, pr in o.found]


def wrong_claims(o: Outcome, at_least: float = 0.0) -> bool:
    return any(pr >= at_least and not o.case.is_right(n) for n, pr in o.found)


@dataclass(frozen=True)
class Figure:
    """One Done-when figure of issue 29 on a set of runs."""

    text: str
    holds: bool | None       # None: nothing to judge it on


TARGET_NAMES = ("every catalogue effect at 10σ named first ≥ 90 % (worst row)",
                "effect-free controls with a claim ≤ 2 %",
                "claims at ≥ 0.99 right ≥ 99 %",
                "unknowns `unexplained` ≥ 90 %",
                "unknowns with a wrong claim at ≥ 0.8 (target: none)",
                "named effect's own gap before ≥ 2× floor (every run)",
                "named effect's own gap after ≤ 1.5× floor (every run)")


def _share(values: list[bool], target, interval: bool) -> Figure:
    text = f"{pct(values, interval)} of {len(values)}"
    return Figure(text, bool(target(float(np.mean(values)))) if values else None)


def targets(outcomes: list[Outcome], interval: bool = False) -> list[Figure]:
    """The issue's Done-when figures on a set of runs, in the order of ``TARGET_NAMES``."""
    rows_10 = [[named_first(o) for o in outs] for outs in by_label(outcomes).values()
               if outs[0].case.group == "effect" and outs[0].case.snr == 10.0]
    tenth = [named_first(o) for o in outcomes if o.case.group == "effect" and o.case.snr == 10.0]
    controls = [bool(o.found) for o in outcomes if o.case.group == "control"]
    unknowns = [o for o in outcomes if o.case.group == "unknown"]
    high = [right for pr, right in claims(outcomes) if pr >= 0.99]
    gaps = [g for g in (own_gap_ok(o) for o in outcomes if o.case.group == "effect") if g is not None]
    worst = min((float(np.mean(r)) for r in rows_10), default=float("nan"))
    first = Figure(f"{100 * worst:.0f} % (pooled {pct(tenth, interval)} of {len(tenth)})",
                   worst >= 0.9 if rows_10 else None)
    return [first,
            _share(controls, lambda r: r <= 0.02, interval),
            _share(high, lambda r: r >= 0.99, interval),
            _share([o.unexplained for o in unknowns], lambda r: r >= 0.9, interval),
            _share([wrong_claims(o, 0.8) for o in unknowns], lambda r: r == 0.0, interval),
            _share([g[0] for g in gaps], lambda r: r == 1.0, interval),
            _share([g[1] for g in gaps], lambda r: r == 1.0, interval)]


def reliability_rows(outcomes: list[Outcome], interval: bool = False) -> list[str]:
    """Claims binned by stated probability: how many, their mean stated value, how many were right."""
    stated = claims(outcomes)
    lines = ["| stated probability | claims | mean stated | right |", "|---|---|---|---|"]
    edges = [0.0, 0.5, 0.8, 0.9, 0.95, 0.99, 1.0001]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = [(pr, right) for pr, right in stated if lo <= pr < hi]
        mean = f"{np.mean([pr for pr, _ in inside]):.3f}" if inside else "–"
        lines.append(f"| {lo:.2f} – {min(hi, 1.0):.2f} | {len(inside)} | {mean} | "
                     f"{pct([r for _, r in inside], interval)} |")
    return lines


def effect_rows(rows: dict[tuple[str, str], list[Outcome]], interval: bool = False) -> list[str]:
    lines = ["| profile | hidden effect | runs | named first | own gap before ≥ 2× floor | "
             "own gap after ≤ 1.5× floor | median CPU s |", "|---|---|---|---|---|---|---|"]
    for (p, label), outs in rows.items():
        if outs[0].case.group != "effect":
            continue
        gaps = [g for g in (own_gap_ok(o) for o in outs) if g is not None]
        lines.append(f"| {p} | {cell(label)} | {len(outs)} | {pct([named_first(o) for o in outs], interval)} | "
                     f"{pct([g[0] for g in gaps])} | {pct([g[1] for g in gaps])} | "
                     f"{np.median([o.cpu_seconds for o in outs]):.1f} |")
    return lines


def other_rows(rows: dict[tuple[str, str], list[Outcome]], interval: bool = False) -> list[str]:
    """Controls and unknowns: unexplained, wrong claims (any, ≥ 0.8), a hidden catalogue effect named."""
    lines = ["| profile | case | runs | `unexplained` | any wrong claim | wrong claims ≥ 0.8 | "
             "hidden catalogue effect named | what was named |", "|---|---|---|---|---|---|---|---|"]
    for (p, label), outs in rows.items():
        if outs[0].case.group == "effect":
            continue
        names = sorted({n for o in outs for n, _ in o.found})
        hidden = pct([any(o.case.is_right(n) for n, _ in o.found) for o in outs]) if outs[0].case.hidden else "–"
        lines.append(f"| {p} | {cell(label)} | {len(outs)} | {pct([o.unexplained for o in outs], interval)} | "
                     f"{pct([wrong_claims(o) for o in outs], interval)} | "
                     f"{pct([wrong_claims(o, 0.8) for o in outs], interval)} | {hidden} | "
                     f"{', '.join(names) or '–'} |")
    return lines


def write_section(path: Path, begin: str, end: str, section: str) -> None:
    """Put ``section`` between the markers in ``path`` (appended with them when they are not there)."""
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    block = f"{begin}\n{section}{end}\n"
    if begin in text and end in text:
        text = re.sub(re.escape(begin) + ".*?" + re.escape(end) + "\n?", lambda _m: block, text, flags=re.S)
    else:
        text = text.rstrip("\n") + "\n\n" + block
    path.write_text(text, encoding="utf-8")


#: a marked section (``<!-- name:begin -->`` … ``<!-- name:end -->``) that another script owns
MARKED_SECTION = re.compile(r"<!-- ([a-z-]+):begin -->.*?<!-- \1:end -->\n?", re.S)


def marked_sections(text: str) -> str:
    """Every marked section of ``text``, in order, for a script that rewrites the rest."""
    return "\n".join(m.group(0) for m in MARKED_SECTION.finditer(text))
