from pathlib import Path

import pytest

from gyrocal.orchestrator.machine import MachineError, RunStateMachine, mermaid_diagram


def test_a_normal_night_walks_through_the_documented_states():
    m = RunStateMachine()
    for trigger, state in [
        ("connect", "connecting"), ("identified", "preflight"), ("preflight_ok", "ready"),
        ("ramp", "ramping"), ("soak", "soaking"), ("stable", "ready"),
        ("spin", "spinning"), ("settle", "settling"), ("log", "logging"), ("logged", "ready"),
        ("log", "logging"), ("logged", "ready"),
        ("analyse", "analysing"), ("report", "reporting"), ("finish", "done"),
    ]:
        getattr(m, trigger)()
        assert m.state == state


@pytest.mark.parametrize(
    "setup, illegal",
    [
        ([], "ramp"),                                              # no ramp before preflight
        (["connect", "identified", "preflight_ok", "ramp"], "spin"),  # no spinning while ramping
        (["connect", "identified", "preflight_ok", "ramp"], "log"),
        (["connect", "identified", "preflight_ok", "spin"], "analyse"),
        (["connect"], "finish"),
    ],
)
def test_illegal_moves_raise(setup, illegal):
    m = RunStateMachine()
    for trigger in setup:
        getattr(m, trigger)()
    with pytest.raises(MachineError):
        getattr(m, illegal)()


def test_no_implicit_shortcuts_exist():
    m = RunStateMachine()
    assert not hasattr(m, "to_done")


def test_a_fault_from_any_active_state_leads_to_safing_then_faulted():
    for steps in (["connect"], ["connect", "identified", "preflight_ok", "ramp", "soak"],
                  ["connect", "identified", "preflight_ok", "spin", "settle", "log"]):
        m = RunStateMachine()
        for trigger in steps:
            getattr(m, trigger)()
        m.fault()
        assert m.state == "safing"
        m.safed()
        assert m.state == "faulted"
        with pytest.raises(MachineError):
            m.fault()


def test_the_docs_diagram_is_drawn_from_the_machine():
    doc = (Path(__file__).parents[2] / "docs" / "state-machine.md").read_text()
    assert mermaid_diagram() in doc
