"""The table_interference step: a dry run logs the drive powered, then off, and the report compares.

Real drivers against the simulators (stations/sim-table-interference.yaml: the
simulated drive adds the vendor notes' 12.48/24.96/37.44 Hz family at 30/15/8
deg/h and 55 deg/h of white noise while the interlock is closed).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrocal.cli import main
from tests.support.dry_run import dry_run, sim_procedure

REPO = Path(__file__).resolve().parents[2]

PROCEDURE = sim_procedure(
    "table interference (test)", "model: FOG, serial: SIM-INTF",
    REPO / "stations" / "sim-table-interference.yaml", ["settle: 2 s", "accel_dps2: 50.0"],
    """\
sequence:
  - setpoint_c: 25.0
    tests: [{kind: table_interference, duration: 5 min}]
""")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("intf")
    (tmp / "p.yaml").write_text(PROCEDURE)
    return dry_run(tmp / "p.yaml", tmp / "run")


def test_the_report_finds_the_drive_lines_and_the_drift_ratio(run: Path) -> None:
    results = json.loads((run / "report" / "results.json").read_text())
    (pair,) = results["table_interference"]
    assert (pair["powered_step"], pair["off_step"]) == ("T01.interference.powered",
                                                        "T01.interference.off")
    lines = pair["lines"]
    assert [round(x["frequency_hz"], 2) for x in lines] == [12.48, 24.96, 37.44]
    # standard error of an LS sine amplitude: sqrt(9.49² + 55²)·sqrt(2/75000) = 0.29 deg/h
    tolerance = 4 * np.hypot(9.49, 55.0) * np.sqrt(2 / 75_000)
    for line, truth in zip(lines, (30.0, 15.0, 8.0), strict=True):
        assert line["amplitude_dph"] == pytest.approx(truth, abs=tolerance)
        assert line["amplitude_off_dph"] < 1.0
    assert 4.5 < pair["drift_ratio"] < 7.5          # sqrt(9.49² + 55²)/9.49 = 5.9 (white parts)


def test_the_interlock_is_opened_read_back_and_closed_again(run: Path) -> None:
    events = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
    drive = [(e["drive"], e["interlock_closed"]) for e in events if e["event"] == "table_drive"]
    assert drive == [("off", False), ("on", True)]
    names = [(e["event"], e.get("step_id")) for e in events]
    off_at = names.index(("table_drive", "T01.interference.off"))
    assert names.index(("step_started", "T01.interference.off")) > off_at
    assert main(["verify", str(run)]) == 0


def test_the_report_page_shows_the_comparison(run: Path) -> None:
    html = (run / "report" / "report.html").read_text()
    assert "Table-induced interference (drive powered vs off)" in html
    assert "T01.interference.off (drive off, interlock open)" in html
    assert "<td>12.48" in html and "Harmonic of the lowest" in html
