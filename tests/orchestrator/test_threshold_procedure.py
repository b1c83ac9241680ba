"""The threshold test kind in the procedure language: located errors, plan ids and ETA."""

from __future__ import annotations

import pytest

from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import ThresholdTest, load_procedure
from tests.orchestrator.test_procedure_validation import BASE, edit, folder, line_of, problems_for

__all__ = ["folder"]   # the fixture, imported for its use below
pytestmark = pytest.mark.timeout(30)

THRESHOLD = """      - {kind: allan, duration: 1 h}
      - kind: threshold
        base_rates_dps: [0, -10]
        increments_dps: [0.01, 0.02, 0.05]
        dwell: 20 s
"""


def with_threshold(text: str = THRESHOLD) -> str:
    return edit("      - {kind: allan, duration: 1 h}\n", text)


def test_a_threshold_test_parses_with_its_defaults(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(with_threshold(), encoding="utf-8")
    test = load_procedure(path).sequence[1].tests[-1]
    assert test == ThresholdTest((0.0, -10.0), (0.01, 0.02, 0.05), 20.0, 10.0, 20.0, 0.95, 0.5,
                                 1, None)


def test_the_plan_alternates_base_and_increment_with_stable_ids_and_durations(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(with_threshold(), encoding="utf-8")
    plan = expand_plan(load_procedure(path))
    steps = [s for s in plan.steps if s.kind == "threshold"]
    assert [s.step_id for s in steps[:7]] == [
        "T02.thr.+0dps.ref0", "T02.thr.+0dps.+0.01dps", "T02.thr.+0dps.ref1",
        "T02.thr.+0dps.+0.02dps", "T02.thr.+0dps.ref2", "T02.thr.+0dps.+0.05dps",
        "T02.thr.+0dps.ref3"]
    assert [s.rate_dps for s in steps[7:]] == [-10.0, -9.99, -10.0, -9.98, -10.0, -9.95, -10.0]
    assert {s.base_rate_dps for s in steps} == {0.0, -10.0}
    assert all(s.confidence == 0.95 and s.max_error_fraction == 0.5 for s in steps)
    # each: settle 10 s + dwell 20 s, plus the move at 20 deg/s² (after the allan hold at
    # rest: none; 0 → -10 deg/s: 0.5 s; -10 → -9.99: 0.5 ms)
    assert steps[0].expected_s == pytest.approx(30.0)
    assert steps[7].expected_s == pytest.approx(30.0 + 10.0 / 20)
    assert steps[8].expected_s == pytest.approx(30.0 + 0.01 / 20)
    assert plan.total_s == pytest.approx(steps[-1].start_s + steps[-1].expected_s)


@pytest.mark.parametrize(("old", "new", "fragment", "message"), [
    ("[0.01, 0.02, 0.05]", "[0.01, 0.05, 0.02]", "increments_dps",
     "increments_dps[2]: 0.02 deg/s is not larger than the increment before it (0.05 deg/s); "
     "list them smallest first"),
    ("[0, -10]", "[0, 399.99]", "base_rates_dps",
     "base_rates_dps[1]: 400.04 deg/s exceeds the table limit 400 deg/s "
     "(procedure safety.table.max_rate_dps)"),
    ("        dwell: 20 s\n", "        dwell: 20 s\n        confidence: 0.4\n", "confidence",
     "confidence: 0.4 must be greater than 0.5"),
    ("[0.01, 0.02, 0.05]", "[0.01, 0.0000001]", "increments_dps",
     "increments_dps[1]: 1e-07 deg/s is finer than a table demand carries"),
])
def test_bad_threshold_keys_are_reported_at_their_line(folder, old, new, fragment, message):
    text = with_threshold(THRESHOLD.replace(old, new))
    problems, path = problems_for(folder, text)
    line = line_of(text, fragment)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"{path}:{line}: sequence[1].tests[3].{message}"), problems


def test_missing_increments_is_one_located_problem(folder):
    text = with_threshold(THRESHOLD.replace("        increments_dps: [0.01, 0.02, 0.05]\n", ""))
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, 'kind: threshold')}: "
                        "sequence[1].tests[3].increments_dps: required key is missing"]


def test_a_threshold_limit_needs_a_threshold_test(folder):
    text = BASE + "  - {name: thr, metric: threshold.threshold_dps, max: 0.1, unit: deg/s}\n"
    problems, _ = problems_for(folder, text)
    assert len(problems) == 1 and "it needs a threshold test in the sequence" in problems[0]


LIMIT = """      - {kind: allan, duration: 1 h}
      - kind: rate_limit
        rates_dps: [100, 200, 300, 400]
        fit_rates: 2
"""


def test_a_rate_limit_walk_plans_each_way_upwards(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(with_threshold(LIMIT), encoding="utf-8")
    steps = [s for s in expand_plan(load_procedure(path)).steps if s.kind == "rate_limit"]
    assert [s.step_id for s in steps] == [f"T02.lim.{sign}{r}dps" for sign in "+-"
                                          for r in (100, 200, 300, 400)]
    assert {(s.fit_rates, s.linearity_tolerance_pct, s.duration_s) for s in steps} == {
        (2, 1.0, 60.0)}


@pytest.mark.parametrize(("old", "new", "fragment", "message"), [
    ("[100, 200, 300, 400]", "[100, 300, 200]", "[100, 300, 200]",
     "rates_dps[2]: 200 deg/s is not larger than the rate before it (300 deg/s); the walk goes up"),
    ("[100, 200, 300, 400]", "[100, 200, 500]", "[100, 200, 500]",
     "rates_dps[2]: 500 deg/s exceeds the table limit 400 deg/s"),
    ("fit_rates: 2", "fit_rates: 4", "fit_rates",
     "fit_rates: 4 fit rates leave none of the 4 rates_dps to walk beyond the linear fit"),
])
def test_bad_rate_limit_keys_are_reported_at_their_line(folder, old, new, fragment, message):
    text = with_threshold(LIMIT.replace(old, new))
    problems, path = problems_for(folder, text)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"{path}:{line_of(text, fragment)}: sequence[1].tests[3]."
                                  f"{message}"), problems


def test_a_positive_rate_limit_cannot_carry_a_negative_limit(folder):
    text = with_threshold(LIMIT.replace("fit_rates: 2", "fit_rates: 2\n        directions: positive"))
    text += "  - {name: neg, metric: rate_limits.max_negative_dps, min: 100, unit: deg/s}\n"
    problems, _ = problems_for(folder, text)
    assert len(problems) == 1 and "it needs a rate_limit test walking the negative direction" \
        in problems[0], problems
