"""Preflight refuses a chamber that runs its own profile (F4 register 200 = 2, issue 8;
F4T register 16568 = 149, issue 23)."""

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


def test_an_f4t_running_its_own_profile_is_not_driven(h: Any, tmp_path: Path, capsys) -> None:
    """F4T: register 16568 reads 149 (Espec watlowf4t.py get_status: running); preflight
    refuses before any step, names the state, leaves the rig safe, exit 3."""
    procedure = h.write_procedure(tmp_path)
    station = tmp_path / "station.yaml"
    text = station.read_text()
    text = text.replace("driver: watlow_f4 ", "driver: watlow_f4t")
    text = text.replace("  limit_input: 1 ", "  # limit_input: 1 ")
    assert "driver: watlow_f4t" in text
    station.write_text(text)
    out = tmp_path / "run"
    code = main(["run", str(procedure), "--sim", "--out", str(out),
                 "--inject", "chamber.profile_running:always"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "preflight: the controller is running its own profile (profile running)" in err
    events = h.events(out)
    assert any(e["event"] == "instrument_identified" and e["driver"] == "watlow_f4t" for e in events)
    assert not any(e["event"] == "step_started" for e in events)
    assert any(e["event"] == "safe_state" for e in events)
