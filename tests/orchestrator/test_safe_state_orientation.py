"""The safe state by table orientation, through ``gyrocal run --sim`` against the real
simulators: a horizontal axis (stations/sim-tilt.yaml, the tilt test's indexing head) is
held at rest under servo after a fault, because a servo-off axis lets an unbalanced load
swing down; a vertical axis (the default) is switched to ``:Mode:Off`` as before.

What the table ended in is read from the simulated table itself (its physics: mode,
rate), not from what the engine printed or journaled.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main

from .test_tilt_linearity_step import _write

pytestmark = pytest.mark.timeout(180)


def _safe_state(out: Path, h: Any) -> dict[str, Any]:
    return [e for e in h.events(out) if e["event"] == "safe_state"][-1]


def _at_rest(sim: Any) -> bool:
    table = sim.table_physics
    return abs(float(table.rate_dps(sim.clock.now_s() + 2.0))) < 1e-9


def test_a_fault_in_a_tilt_step_leaves_a_horizontal_table_servoing_at_rest(
        h: Any, tmp_path: Path, sim_capture, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(_write(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "chamber.alarm:always@T01.tilt.+30deg"], on_sim_started=sim_capture)
    assert code == EXIT_FAULT
    sim = sim_capture.last
    assert sim.table_physics.mode == "position"          # servo on: never "off"
    assert _at_rest(sim)
    err = capsys.readouterr().err
    assert "table held at rest under servo (horizontal axis; read back 0.0" in err
    assert "mode position" in err
    safe = _safe_state(out, h)
    assert safe["confirmed"]["table"] is True
    assert safe["actions"]["table"].startswith("table held at rest under servo (horizontal axis")
    assert main(["resume", str(out)]) == EXIT_OK


def test_an_open_interlock_on_a_horizontal_table_is_not_confirmed_safe(
        h: Any, tmp_path: Path, sim_capture, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(_write(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "table.interlock_open:always@T01.tilt.+30deg"],
                on_sim_started=sim_capture)
    assert code == EXIT_FAULT
    assert sim_capture.last.table_physics.mode == "off"  # the interlock dropped the servo
    err = capsys.readouterr().err
    assert "TABLE NOT CONFIRMED SAFE" in err and "interlock open" in err
    assert "INSTRUMENTS NOT CONFIRMED SAFE" in err
    safe = _safe_state(out, h)
    assert safe["confirmed"]["table"] is False
    assert "interlock open" in safe["actions"]["table"]


def test_a_fault_leaves_a_vertical_table_in_mode_off(h: Any, tmp_path: Path, sim_capture) -> None:
    sim_capture.arm.append(lambda sim: h.when_table_commanded(
        sim, 20.0, lambda: sim.chamber_faults.arm("alarm", count=None)))
    out = tmp_path / "run"
    code = main(["run", str(h.write_procedure(tmp_path, max_repeats=1)), "--sim", "--out",
                 str(out), "--seed", "5"], on_sim_started=sim_capture)
    assert code == EXIT_FAULT
    sim = sim_capture.last
    assert sim.table_physics.mode == "off"
    assert _at_rest(sim)
    assert _safe_state(out, h)["actions"]["table"].startswith("table stopped (read back 0.0")


def test_the_plan_says_what_the_safe_state_does_for_each_orientation(h: Any, tmp_path: Path,
                                                                      capsys) -> None:
    assert main(["plan", str(_write(tmp_path))]) == EXIT_OK
    horizontal = capsys.readouterr().out
    assert "Safe state (a fault, the end): table held at rest under servo in position mode" \
        in horizontal
    assert ":Mode:Off" not in horizontal
    assert main(["plan", str(h.write_procedure(tmp_path))]) == EXIT_OK
    vertical = capsys.readouterr().out
    assert "Safe state (a fault, the end): table stopped, then servo off (:Mode:Off)" in vertical
