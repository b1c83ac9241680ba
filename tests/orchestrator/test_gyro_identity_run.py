"""The unit under test says who it is: its start-up datagrams journaled, its serial checked.

A dry run of the small procedure on the simulated station with the unit on the
simulated E36300 (it starts sending ``gyro_startup_s`` after the output-on):
the simulated STIM300 sends its part number, serial number and configuration
datagrams when it starts (TS1524 §7.5.1, p. 47) and answers ``N<CR>`` and
``I<CR>`` (§8.1–8.2, p. 58) with the serial of the procedure's unit under
test. The run journals both, the gyro's identity line carries them, and the
report checks the serial against the procedure's as it does the table's
against the station's: a different one blocks the PASS.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from pypdf import PdfReader

from gyrocal.cli import EXIT_OK, main
from gyrocal.instruments.sim.stim_identity import SIM_PART_NUMBER
from gyrocal.reports.build import build_report

pytestmark = pytest.mark.timeout(180)

SERIAL = "N00000000004242"
SUPPLY = """
supply:
  driver: keysight_e36300
  address: sim
  channel: 1
  identity: {make: Keysight, model: E36312A, serial: MY-T-1}
  voltage_v: 5.0
  current_limit_a: 0.5
  safe_state: {unit_power: keep_on}
  timeout_s: 0.3
  retries: 2
"""


def _powered_run(h: Any, folder: Path, serial: str) -> Path:
    procedure = h.write_procedure(folder)
    procedure.write_text(procedure.read_text().replace("serial: SIM-T", f"serial: {serial}"))
    station = folder / "station.yaml"
    station.write_text(station.read_text().replace(
        "\nsimulation:", SUPPLY + "\nsimulation:\n  gyro_startup_s: 0.3"))
    out = folder / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out)]) in (EXIT_OK, 1)
    return out


def test_the_unit_says_who_it_is_at_power_on_and_when_asked_and_the_report_checks_it(h, tmp_path):
    out = _powered_run(h, tmp_path, SERIAL)
    events = h.events(out)
    start_up = [e for e in events if e["event"] == "gyro_start_up"]
    assert len(start_up) == 1 and start_up[0]["when"] == "preflight"
    assert start_up[0]["datagrams"] == ["part number", "serial number", "configuration"]
    assert (start_up[0]["serial"], start_up[0]["part_number"]) == (SERIAL, SIM_PART_NUMBER)
    asked = [e for e in events if e["event"] == "gyro_identity"]
    assert [(e["serial"], e["part_number"], e["revision"]) for e in asked] == [
        (SERIAL, SIM_PART_NUMBER, "G")]
    gyro = [e for e in events if e["event"] == "instrument_identified" and e["role"] == "gyro"]
    assert f"unit part number {SIM_PART_NUMBER} rev G, serial {SERIAL}" in gyro[-1]["description"]
    results = json.loads((out / "report" / "results.json").read_text())
    entry = results["instruments"]["gyro"]
    assert (entry["reported_serial"], entry["identity_mismatch"]) == (SERIAL, False)
    assert f"unit part number {SIM_PART_NUMBER} rev G, serial {SERIAL}" in entry["description"]
    assert not any("gyro" in reason for reason in results["verdict"]["blocked_because"])
    assert main(["certificate", str(out), "--customer", "ACME", "--number", "GC-1",
                 "--approved-by", "A. Auditor", "--role", "Quality manager"]) == EXIT_OK
    pdf = " ".join(page.extract_text() for page in PdfReader(out / "report" / "certificate.pdf").pages)
    assert f"serial {SERIAL} (the unit reports serial {SERIAL})" in " ".join(pdf.split())
    # the same run declared for another unit: the unit's own word contradicts it
    plan_path = out / "plan.json"
    plan = json.loads(plan_path.read_text())
    plan["unit_under_test"]["serial"] = "N00000000001111"
    plan_path.write_text(json.dumps(plan))
    rebuilt = build_report(out)
    assert rebuilt["verdict"]["overall"] == "BLOCKED"
    assert rebuilt["instruments"]["gyro"]["identity_mismatch"] is True
    assert any("'N00000000001111'" in reason and SERIAL in reason
               for reason in rebuilt["verdict"]["blocked_because"])


def test_a_serial_the_unit_cannot_say_is_not_confirmed_and_not_a_fault(h, tmp_path):
    out = _powered_run(h, tmp_path, "SIM-T-7")       # Table 5-15 carries N and 14 digits only
    events = h.events(out)
    asked = [e for e in events if e["event"] == "gyro_identity"]
    assert asked[0]["serial"] is None and asked[0]["part_number"] == SIM_PART_NUMBER
    start_up = [e for e in events if e["event"] == "gyro_start_up"]
    assert start_up[0]["datagrams"] == ["part number", "configuration"]
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["instruments"]["gyro"]["reported_serial"] is None
    assert results["instruments"]["gyro"]["identity_mismatch"] is False
