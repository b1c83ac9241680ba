"""The unit under test powered by the simulated E36300: power on, readings journaled, faults safe.

Runs go through ``gyrocal.cli.main`` against the real simulators on loopback
(the supply is a SCPI server reached by the E36300 driver over pyvisa-py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main

SUPPLY = """
supply:
  driver: keysight_e36300
  address: sim
  channel: 1
  identity: {{make: Keysight, model: E36312A, serial: MY-T-1}}
  voltage_v: 5.0
  current_limit_a: 0.5
  safe_state: {{unit_power: {action}}}
  timeout_s: 0.3
  retries: 2
"""


def _powered(h: Any, folder: Path, action: str = "keep_on") -> Path:
    procedure = h.write_procedure(folder)
    station = folder / "station.yaml"
    station.write_text(station.read_text().replace("\nsimulation:",
                                                   SUPPLY.format(action=action) + "\nsimulation:"))
    return procedure


@pytest.mark.timeout(120)
def test_the_unit_is_powered_at_connect_and_read_back_after_every_logged_step(h, tmp_path):
    out = tmp_path / "run"
    assert main(["run", str(_powered(h, tmp_path)), "--sim", "--out", str(out)]) in (EXIT_OK, 1)
    reads = [e for e in h.events(out) if e["event"] == "supply_read"]
    logged = [s for s in h.SMALL_PLAN if ".ramp" not in s and ".soak" not in s]
    assert [e["step_id"] for e in reads] == [None, *logged]
    assert reads[0]["when"] == "power_on"
    for event in reads:     # 5 V into the simulated 20 Ω unit: 0.25 A
        assert event["ok"] and event["output_on"] and event["voltage_v"] == 5.0
        assert event["current_a"] == pytest.approx(0.25, abs=0.002)
    identified = [e for e in h.events(out) if e["event"] == "instrument_identified"]
    assert any(e["role"] == "supply" and "E36312A" in e["description"] for e in identified)


@pytest.mark.timeout(120)
def test_an_overcurrent_is_a_fault_the_unit_kept_powered_and_the_run_resumes(h, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(_powered(h, tmp_path, "keep_on")), "--sim", "--out", str(out),
                 "--inject", "supply.overcurrent:always@T01.sf.+20dps"])
    assert code == EXIT_FAULT
    assert "over-current" in capsys.readouterr().err
    events = h.events(out)
    fault = [e for e in events if e["event"] == "fault"][-1]
    assert fault["instrument"] == "supply" and fault["step_id"] == "T01.sf.+20dps"
    safe = [e for e in events if e["event"] == "safe_state"][-1]
    assert safe["confirmed"] == {"table": True, "chamber": True, "supply": True}
    assert safe["actions"]["supply"].startswith("unit power kept on (read back")
    assert main(["resume", str(out)]) in (EXIT_OK, 1)    # 1: acceptance; never a fault again
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)


@pytest.mark.timeout(120)
def test_a_supply_that_drops_out_is_a_fault_and_switch_off_is_confirmed_by_read_back(h, tmp_path,
                                                                                      capsys):
    out = tmp_path / "run"
    code = main(["run", str(_powered(h, tmp_path, "switch_off")), "--sim", "--out", str(out),
                 "--inject", "supply.dropout:always@T02.sf.+20dps"])
    assert code == EXIT_FAULT
    assert "dropped out" in capsys.readouterr().err
    safe = [e for e in h.events(out) if e["event"] == "safe_state"][-1]
    assert safe["actions"]["supply"] == "unit power switched off (read back: output off)"
    assert safe["confirmed"]["supply"] is True


@pytest.mark.timeout(60)
def test_keep_on_after_a_dropout_is_not_claimed_safe(h, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(_powered(h, tmp_path, "keep_on")), "--sim", "--out", str(out),
                 "--inject", "supply.dropout:always@T01.static"])
    assert code == EXIT_FAULT
    err = capsys.readouterr().err
    assert "SUPPLY NOT CONFIRMED SAFE" in err
    safe = [e for e in h.events(out) if e["event"] == "safe_state"][-1]
    assert safe["confirmed"]["supply"] is False


def test_a_bad_supply_section_is_refused_naming_file_line_and_key(h, tmp_path, capsys):
    procedure = _powered(h, tmp_path, "maybe")
    station = tmp_path / "station.yaml"
    line = station.read_text().splitlines().index("  safe_state: {unit_power: maybe}") + 1
    assert main(["validate", str(procedure)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert f"{station}:{line}: supply.safe_state.unit_power: expected one of keep_on, switch_off" in err
