"""The turn_on test kind in the procedure language: located errors, plan ids, ETA."""

from __future__ import annotations

import shutil

import pytest

from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import TurnOnTest, load_procedure
from gyrocal.orchestrator.turn_on import FIRST_FRAME_TIMEOUT_S
from gyrocal.record.step_kind import StepKind
from tests.orchestrator.test_procedure_validation import (
    REPO,
    edit,
    folder,
    line_of,
    problems_for,
)

__all__ = ["folder"]   # the fixture, imported for its use below
pytestmark = pytest.mark.timeout(30)

TURN_ON = """      - {kind: allan, duration: 1 h}
      - kind: turn_on
        off: 30 s
        duration: 10 min
        band_dph: 0.5
"""


def powered(folder, text: str = TURN_ON) -> str:
    """The procedure on a copy of the powered station (sim-powered.yaml has a supply)."""
    shutil.copy(REPO / "stations" / "sim-powered.yaml", folder / "stations" / "sim.yaml")
    return edit("      - {kind: allan, duration: 1 h}\n", text)


def test_a_turn_on_test_parses_and_plans_its_off_time_in_the_eta(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(powered(folder), encoding="utf-8")
    procedure = load_procedure(path)
    assert procedure.sequence[1].tests[-1] == TurnOnTest(30.0, 600.0, 0.5, 1, None)
    steps = [s for s in expand_plan(procedure).steps if s.kind == StepKind.TURN_ON]
    assert [s.step_id for s in steps] == ["T02.turnon"]
    # settle is the off time; the worst case allows the unit its first-frame timeout
    assert (steps[0].settle_s, steps[0].duration_s, steps[0].band_dph) == (30.0, 600.0, 0.5)
    assert steps[0].expected_s == 630.0 + steps[0].transition_s
    assert steps[0].max_s == steps[0].expected_s + FIRST_FRAME_TIMEOUT_S


def test_a_turn_on_test_without_a_supply_is_refused_at_its_kind(folder):
    text = edit("      - {kind: allan, duration: 1 h}\n", TURN_ON)   # sim.yaml: no supply
    problems, path = problems_for(folder, text)
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"{path}:{line_of(text, 'kind: turn_on')}: "
                                  "sequence[1].tests[3].kind: a turn_on test switches the "
                                  "unit's power; the station "), problems


@pytest.mark.parametrize("old, new, fragment, message", [
    ("band_dph: 0.5", "band_dph: 0", "band_dph: 0", "band_dph:"),
    ("band_dph: 0.5", "band: 0.5", "band: 0.5", "band:"),
    ("off: 30 s", "off: -3 s", "off: -3 s", "off:"),
])
def test_bad_turn_on_keys_are_reported_at_their_line(folder, old, new, fragment, message):
    text = powered(folder, TURN_ON.replace(old, new))
    problems, path = problems_for(folder, text)
    assert problems, text
    located = f"{path}:{line_of(text, fragment)}: sequence[1].tests[3].{message}"
    assert any(p.startswith(located) for p in problems), problems


def test_a_turn_on_limit_needs_a_turn_on_test(folder):
    text = (powered(folder, "      - {kind: allan, duration: 1 h}\n")
            + "  - {name: t, metric: turn_on.warmup_tau_s, max: 60, unit: s}\n")
    problems, _ = problems_for(folder, text)
    assert any("it needs a turn_on test in the sequence" in p for p in problems), problems


REPEAT = """      - {kind: allan, duration: 1 h}
      - {kind: turn_on_repeatability, cycles: 4, off: 2 min, settle: 5 min, duration: 1 min}
"""


def test_a_repeatability_test_plans_one_step_per_cycle_with_its_cool_down(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(powered(folder, REPEAT), encoding="utf-8")
    steps = [s for s in expand_plan(load_procedure(path)).steps
             if s.kind == StepKind.TURN_ON_CYCLE]
    assert [s.step_id for s in steps] == [f"T02.rep.c{n}" for n in range(1, 5)]
    # off 120 s + settle 300 s before each 60 s record
    assert {(s.off_s, s.settle_s, s.duration_s) for s in steps} == {(120.0, 420.0, 60.0)}


def test_a_repeatability_test_needs_two_cycles_and_a_supply(folder):
    text = powered(folder, REPEAT.replace("cycles: 4", "cycles: 1"))
    problems, path = problems_for(folder, text)
    assert any(p.startswith(f"{path}:{line_of(text, 'cycles: 1')}: sequence[1].tests[3].cycles")
               for p in problems), problems
    shutil.copy(REPO / "stations" / "sim.yaml", folder / "stations" / "sim.yaml")
    problems, _ = problems_for(folder, edit("      - {kind: allan, duration: 1 h}\n", REPEAT))
    assert any("a turn_on_repeatability test switches the unit's power" in p
               for p in problems), problems
