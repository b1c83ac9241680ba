"""Preflight refuses a chamber that runs its own profile (F4 register 200 = 2; issue 8)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gyrocal.cli import EXIT_FAULT, main


def test_a_controller_running_its_own_profile_is_not_driven(h: Any, tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "chamber.profile_running:always"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "preflight: the controller is running its own profile (profile running)" in err
    events = h.events(out)
    assert not any(e["event"] == "step_started" for e in events)
    assert any(e["event"] == "safe_state" for e in events)
