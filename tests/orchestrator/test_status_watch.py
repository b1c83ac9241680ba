"""`gyrocal status` (text and --json) and the watch server's access rules, from run folders."""

from __future__ import annotations

import json
import os
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from gyrocal.app.watch.server import WatchServer
from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.journal import Journal
from gyrocal.record.locks import run_folder_lock


def _faulted(h: Any, tmp_path: Path) -> Path:
    out = tmp_path / "run"
    assert main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "table.interlock_open:always@T02.sf.+20dps"]) == EXIT_FAULT
    return out


def test_status_json_and_text_of_a_faulted_run(h: Any, tmp_path: Path, capsys) -> None:
    out = _faulted(h, tmp_path)
    capsys.readouterr()
    assert main(["status", "--json", str(out)]) == EXIT_OK
    snap = json.loads(capsys.readouterr().out)
    assert snap["state"] == "faulted" and snap["live"] is False
    assert snap["step_count"] == len(h.SMALL_PLAN) and snap["steps_done"] == 7
    assert snap["current_step"] == "T02.sf.+20dps" and snap["current_index"] == 8
    plan = {s["step_id"]: s["expected_s"] for s in snap["plan"]}
    assert snap["eta_s"] == pytest.approx(plan["T02.sf.+20dps"] + plan["T02.sf.-20dps"])
    assert snap["faults"][-1]["event"] == "fault" and "interlock" in snap["last_fault"].lower()
    assert main(["status", str(out)]) == EXIT_OK
    text = capsys.readouterr().out
    assert "state: faulted" in text and "7/9 completed; next: T02.sf.+20dps" in text
    assert "ETA (plan, procedure time): 00:00:" in text and "held by: nobody" in text


def _hand_made_run(folder: Path, *, last_event: str, age_s: float) -> Path:
    """A run folder as interfaces.md lays it out, written by hand: a live controller (us)."""
    folder.mkdir()
    (folder / "manifest.json").write_text(json.dumps(
        {"run_id": "R1", "state": "running", "pid": os.getpid(),
         "unit_under_test": {"serial": "SN-9"}}))
    (folder / "plan.json").write_text(json.dumps({"sample_rate_hz": 200.0, "steps": [
        {"step_id": "T01.ramp", "kind": "ramp", "setpoint_c": 30.0, "rate_dps": 0.0,
         "expected_s": 600.0},
        {"step_id": "T01.soak", "kind": "soak", "setpoint_c": 30.0, "rate_dps": 0.0,
         "expected_s": 1800.0}]}))
    with Journal(folder / "journal.jsonl") as journal:
        journal.append("step_started", step_id="T01.ramp")
        journal.append("step_completed", step_id="T01.ramp")
        journal.append(last_event, before_step="T01.soak")
    lines = (folder / "journal.jsonl").read_text().splitlines()
    last = json.loads(lines[-1])
    last["wall_time"] = time.time() - age_s      # what the clock said when it was written
    (folder / "journal.jsonl").write_text("\n".join(lines[:-1] + [json.dumps(last)]) + "\n")
    return folder


def test_status_shows_paused_and_warns_when_a_live_run_goes_silent(tmp_path: Path,
                                                                    capsys) -> None:
    paused = _hand_made_run(tmp_path / "paused", last_event="paused", age_s=3600)
    assert main(["status", str(paused)]) == EXIT_OK
    text = capsys.readouterr().out
    assert "state: paused" in text and "PAUSED (delete" in text and "WARNING" not in text
    assert "1/2 completed; next: T01.soak" in text and "ETA (plan, procedure time): 00:30:00" in text
    silent = _hand_made_run(tmp_path / "silent", last_event="retry", age_s=3600)
    assert main(["status", "--json", str(silent)]) == EXIT_OK
    snap = json.loads(capsys.readouterr().out)
    assert snap["state"] == "running" and snap["stale"] is True and snap["live"] is True
    assert main(["status", str(silent)]) == EXIT_OK
    assert "WARNING: the controller is alive but the journal has not moved" in capsys.readouterr().out
    with run_folder_lock(silent):                 # a controller holding the folder (issue #9)
        assert main(["status", "--json", str(silent)]) == EXIT_OK
        snap = json.loads(capsys.readouterr().out)
        assert snap["lock"]["pid"] == os.getpid() and snap["lock"]["host"] == socket.gethostname()
        assert main(["status", str(silent)]) == EXIT_OK
        assert f"held by: pid {os.getpid()} on {socket.gethostname()}" in capsys.readouterr().out


def _get(url: str, method: str = "GET") -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, method=method), timeout=10) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def test_watch_is_read_only_and_needs_a_token_off_loopback(tmp_path: Path) -> None:
    run = _hand_made_run(tmp_path / "r", last_event="paused", age_s=1)
    local = WatchServer(run).start()
    try:
        assert local.token is None
        status, body = _get(local.url + "api/snapshot")
        assert status == 200 and json.loads(body)["snapshot"]["paused"] is True
        assert _get(local.url + "uPlot.iife.min.js")[0] == 200
        assert _get(local.url + "api/snapshot", "POST")[0] == 405
        assert _get(local.url + "../manifest.json")[0] == 404
    finally:
        local.stop()
    shared = WatchServer(run, bind="0.0.0.0").start()
    try:
        port = shared.httpd.server_address[1]
        assert shared.token and len(shared.token) >= 20
        assert _get(f"http://127.0.0.1:{port}/api/snapshot")[0] == 403
        assert _get(f"http://127.0.0.1:{port}/api/snapshot?token=wrong")[0] == 403
        assert _get(f"http://127.0.0.1:{port}/api/snapshot?token={shared.token}")[0] == 200
    finally:
        shared.stop()


def test_a_simulator_error_is_shown_as_a_fault(tmp_path: Path) -> None:
    """Issue 28: the live page listed ``simulator_crashed`` as a fault while the run journals
    ``simulator_error`` (commands.py, when a simulated gyro dies), so the page never flagged
    it. The fault list is now JournalEvent members: what the run writes is what is matched."""
    from gyrocal.app.watch.snapshot import FAULT_EVENTS, read_snapshot
    from gyrocal.record.journal import JournalEvent

    run = _hand_made_run(tmp_path / "run", last_event="resumed", age_s=1)
    with Journal(run / "journal.jsonl") as journal:
        journal.append(JournalEvent.SIMULATOR_ERROR,
                       message="simulated gyro stopped: OSError: pty closed")
    snap = read_snapshot(run)
    assert [(f.event, f.fault) for f in snap.faults] == [("simulator_error", True)]
    assert "simulated gyro stopped" in (snap.last_fault or "")
    assert all(isinstance(name, JournalEvent) for name in FAULT_EVENTS)
