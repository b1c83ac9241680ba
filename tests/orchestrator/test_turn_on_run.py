"""A turn_on step whose unit never sends after the output-on is a fault (exit 3), and the
resumed run cycles the power again and recovers the turn-on truths (acceptance series)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.orchestrator import turn_on as turn_on_module

pytestmark = [pytest.mark.timeout(300), pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]


def _events(out: Path, name: str) -> list[dict]:
    return [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()
            if f'"{name}"' in line]


def test_a_silent_unit_after_power_on_faults_and_the_resumed_run_cycles_it_again(tmp_path,
                                                                                   capsys,
                                                                                   monkeypatch):
    out = tmp_path / "run"
    # The first-frame wait polls every 20 ms of clock time and lets each poll wait 50 ms of
    # wall time for bytes already sent, so the product's 30 s limit costs 75 s of wall time
    # even on the simulated clock. A 3 s limit exercises the same path (the silent unit is
    # a fault naming the step and the limit) for a tenth of that; the unit under test
    # starts 0.8 s after its output-on, well inside it, so the resumed run is unchanged.
    monkeypatch.setattr(turn_on_module, "FIRST_FRAME_TIMEOUT_S", 3.0)
    # the supply's output drops out when the turn-on step switches it on: no frame comes
    code = main(["run", str(REPO / "procedures" / "acceptance-series.yaml"), "--sim",
                 "--out", str(out), "--seed", "3", "--inject", "supply.dropout@T01.turnon"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT, err
    assert "T01.turnon: no valid frame within 3 s of the output-on" in err
    faults = _events(out, "fault")
    assert faults[-1]["step_id"] == "T01.turnon"
    assert _events(out, "unit_power_cycle") == []
    assert main(["resume", str(out)]) == EXIT_OK, capsys.readouterr()
    cycles = _events(out, "unit_power_cycle")
    assert [c["step_id"] for c in cycles][:2] == ["T01.turnon", "T01.rep.c1"]
    # each power-on's start-up datagrams (TS1524 §7.5.1) are cut from the stream and journaled
    # (the procedure's serial SIM-0002 is not one Table 5-15 can carry: no serial datagram)
    start_ups = _events(out, "gyro_start_up")
    cycled = {c["step_id"] for c in cycles}
    assert cycled <= {e["when"] for e in start_ups}
    assert all(e["datagrams"] == ["part number", "configuration"] for e in start_ups)
    results = json.loads((out / "report" / "results.json").read_text())
    turn_on = results["turn_on"]["tests"][0]
    assert abs(turn_on["time_to_first_data_s"] - 0.8) <= turn_on["U_time_to_first_data_s"]
    assert abs(turn_on["warmup_tau_s"] - 10.0) <= turn_on["U_warmup_tau_s"]
