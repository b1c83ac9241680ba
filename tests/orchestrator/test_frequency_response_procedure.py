"""The frequency_response test kind in the procedure language: located errors, plan ids, ETA."""

from __future__ import annotations

import pytest

from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import FrequencyResponseTest, load_procedure
from tests.orchestrator.test_procedure_validation import BASE, edit, folder, line_of, problems_for

__all__ = ["folder"]   # the fixture, imported for its use below
pytestmark = pytest.mark.timeout(30)

SWEEP = """      - {kind: allan, duration: 1 h}
      - kind: frequency_response
        amplitude_dps: 1.0
        frequencies_hz: [0.5, 1, 2]
        phase_at_hz: 1.5
"""


def with_sweep(text: str = SWEEP) -> str:
    return edit("      - {kind: allan, duration: 1 h}\n", text)


def test_a_frequency_response_test_parses_with_its_defaults(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(with_sweep(), encoding="utf-8")
    test = load_procedure(path).sequence[1].tests[-1]
    assert test == FrequencyResponseTest((0.5, 1.0, 2.0), 1.0, 10, 3, 1.0, 1.5, 1, None)


def test_the_plan_has_one_step_per_frequency_with_whole_periods(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(with_sweep(), encoding="utf-8")
    plan = expand_plan(load_procedure(path))
    steps = [s for s in plan.steps if s.kind == "frequency_response"]
    assert [s.step_id for s in steps] == ["T02.freq.0.5Hz", "T02.freq.1Hz", "T02.freq.2Hz"]
    # logged: 10 periods (20, 10, 5 s); settle: 1 s at rest + 3 periods (6, 3, 1.5 s)
    assert [s.duration_s for s in steps] == [20.0, 10.0, 5.0]
    assert [s.settle_s for s in steps] == [7.0, 4.0, 2.5]
    assert [s.expected_s for s in steps] == [27.0, 14.0, 7.5]
    assert {(s.amplitude_dps, s.phase_at_hz, s.rate_dps) for s in steps} == {(1.0, 1.5, 0.0)}


@pytest.mark.parametrize(("old", "new", "fragment", "message"), [
    ("[0.5, 1, 2]", "[0.5, 2, 1]", "[0.5, 2, 1]",
     "frequencies_hz[2]: 1 Hz is not above the frequency before it (2 Hz); the sweep goes up"),
    # stations/sim.yaml samples at 2000 Hz: 300 Hz would have 6.7 samples a period
    ("[0.5, 1, 2]", "[0.5, 1, 300]", "[0.5, 1, 300]",
     "frequencies_hz[2]: 300 Hz has fewer than 10 samples a period at 2000 Hz sampling"),
    # 2π · 10 Hz · 1 deg/s = 62.83 deg/s² against the procedure's 50 deg/s²
    ("[0.5, 1, 2]", "[0.5, 1, 10]", "[0.5, 1, 10]",
     "frequencies_hz[2]: 10 Hz at 1 deg/s peaks at 62.8319 deg/s² (2πf × amplitude), beyond "
     "the table limit 50 deg/s² (procedure safety.table.max_accel_dps2)"),
    ("phase_at_hz: 1.5", "phase_at_hz: 3", "phase_at_hz",
     "phase_at_hz: 3 Hz is outside the swept 0.5..2 Hz"),
    ("amplitude_dps: 1.0", "amplitude_dps: 500", "amplitude_dps",
     "amplitude_dps: 500 deg/s exceeds the table limit 400 deg/s"),
    ("[0.5, 1, 2]", "[1]", "[1]", "frequencies_hz: a sweep needs at least two frequencies"),
])
def test_bad_frequency_response_keys_are_reported_at_their_line(folder, old, new, fragment,
                                                                message):
    text = with_sweep(SWEEP.replace(old, new))
    problems, path = problems_for(folder, text)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"{path}:{line_of(text, fragment)}: sequence[1].tests[3]."
                                  f"{message}"), problems


def test_a_bandwidth_limit_needs_a_frequency_response_test(folder):
    text = BASE + "  - {name: bw, metric: frequency_response.bandwidth_hz, min: 1, unit: Hz}\n"
    problems, _ = problems_for(folder, text)
    assert len(problems) == 1 and "it needs a frequency_response test in the sequence" \
        in problems[0], problems
