"""`gyrocal run --sim --inject`: rehearsing a night's faults against the simulators."""

from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main


@pytest.mark.parametrize(
    "spec, message",
    [
        ("chamber.melt", "the simulated chamber has no fault 'melt'"),
        ("oven.no_reply", "this station has no simulated 'oven'"),
        ("supply.dropout", "this station has no simulated 'supply'"),
        ("chamber-no_reply", "expected ROLE.FAULT"),
        ("table.no_reply:0", "a count must be at least 1"),
        ("gyro.stall@T09.nowhere", "the plan has no step 'T09.nowhere'"),
    ],
)
def test_bad_injections_are_refused_before_anything_moves(h: Any, tmp_path: Path, capsys,
                                                         spec: str, message: str) -> None:
    out = tmp_path / "run"
    assert main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out),
                 "--inject", spec]) == EXIT_BAD_INPUT
    assert message in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.timeout(120)
def test_an_injected_interlock_opening_goes_safe_is_journaled_and_resumes(
        h: Any, tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "table.interlock_open:always@T02.sf.+20dps",
                 "--inject", "chamber.no_reply:1@T01.static"])
    assert code == EXIT_FAULT
    assert "interlock" in capsys.readouterr().err
    events = h.events(out)
    injected = [e for e in events if e["event"] == "fault_injected"]
    assert [(e["instrument"], e["fault"], e["before_step"]) for e in injected] == [
        ("chamber", "no_reply", "T01.static"), ("table", "interlock_open", "T02.sf.+20dps")]
    assert any(e["event"] == "retry" and e["instrument"] == "chamber" for e in events)
    fault = [e for e in events if e["event"] == "fault"][-1]
    assert fault["step_id"] == "T02.sf.+20dps"
    # the rehearsal's faults are not carried into the resumed session: it completes
    assert main(["resume", str(out)]) == EXIT_OK
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)
