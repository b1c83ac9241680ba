"""Ctrl-C and kill -9 of a real ``gyrocal run --sim`` process, then ``gyrocal resume``.

A killed run must leave nothing corrupted (every journaled chunk exists with
its recorded SHA-256, the journal's hash chain verifies, a torn last line is
set aside) and its resumed completion must equal an uninterrupted run with
the same seed: the counted samples value for value, the scale factors bit for
bit (a resumed dry run restores the simulated state, engine.Rehearsal).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import gyrocal.app.watch.status  # noqa: F401 - imported here, not by the first status call mid-run
from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.journal import read_journal
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.samples import read_chunks
from tests.support.fork_server import Forked, ForkServer
from tests.support.short_run import without_report_figures

pytestmark = [pytest.mark.timeout(240), pytest.mark.slow]


def start_run(procedure: Path, out: Path, root: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "gyrocal", "run", str(procedure), "--sim", "--out", str(out),
         "--seed", "5"],
        cwd=root, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_event(out: Path, name: str, proc: subprocess.Popen | Forked, timeout_s: float = 90.0,
                   step_id: str | None = None) -> None:
    """Poll the journal (wall time) until ``name`` appears; the process must still be running."""
    deadline = time.monotonic() + timeout_s
    path = out / "journal.jsonl"
    while time.monotonic() < deadline:
        if path.exists():
            text = path.read_text(errors="replace")
            if f'"event":"{name}"' in text and (step_id is None or f'"step_id":"{step_id}"' in text):
                return
        assert proc.poll() is None, f"run ended early: {proc.communicate()}"
        time.sleep(0.005)
    raise AssertionError(f"{name} never journaled in {out}")


def status_text(run_dir: Path, capsys) -> str:
    capsys.readouterr()
    assert main(["status", str(run_dir)]) == EXIT_OK
    return capsys.readouterr().out


def test_sigint_goes_safe_exits_3_and_resumes(h: Any, tmp_path: Path, capsys) -> None:
    procedure = h.write_procedure(tmp_path)
    out = tmp_path / "run"
    proc = start_run(procedure, out, h.REPO_ROOT)
    try:
        # The live status is read while the run soaks (T01.ramp completed), and the signal is
        # sent the moment the sweep step starts: read between the two, the status (with its
        # lazy imports, ~0.5 s idle) outlasted the last 0.25 s of stepping on a host at load
        # 15-19, and the signal then landed in "reporting", after the last step.
        wait_for_event(out, "step_started", proc, step_id="T01.soak")
        live = status_text(out, capsys)           # gyrocal status on a live run
        assert "state: running" in live and "completed" in live
        wait_for_event(out, "step_started", proc, step_id="T01.sf.+20dps")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == EXIT_FAULT, err
    assert "interrupted" in err and f"gyrocal resume {out}" in err and "Traceback" not in err
    log = h.events(out)
    interrupted = [e for e in log if e["event"] == "interrupted"]
    assert len(interrupted) == 1
    assert interrupted[0]["state"] in ("spinning", "settling", "logging", "ready", "ramping",
                                       "soaking")
    assert interrupted[0]["step_id"] is not None
    assert log[-1]["event"] == "safe_state"
    assert log[-1]["actions"]["table"].startswith("table stopped (read back 0.0")
    assert log[-1]["actions"]["chamber"] == "chamber setpoint 25.0 °C (read back)"
    assert log[-1]["confirmed"] == {"table": True, "chamber": True}
    assert h.manifest(out)["state"] == "faulted"
    faulted = status_text(out, capsys)
    assert "state: faulted" in faulted and "interrupted by the operator" in faulted
    list(read_journal(out / "journal.jsonl"))
    assert main(["resume", str(out)]) == EXIT_OK
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)
    h.assert_chunks_intact(out)
    done = status_text(out, capsys)
    assert "state: done" in done and f"{len(h.SMALL_PLAN)}/{len(h.SMALL_PLAN)} completed" in done


def step_summary(run_dir: Path) -> dict[str, dict[str, Any]]:
    """step_id → samples, rows, and the bytes of the kept attempt's time stamps and output."""
    folder = RunFolder.open(run_dir)
    summary: dict[str, dict[str, Any]] = {}
    for event in folder.journal_events():
        if event["event"] != "step_completed" or "chunks" not in event:
            continue
        columns = read_chunks(folder.path, event["chunks"])
        gyro = np.asarray(columns["gyro"])
        summary[event["step_id"]] = {
            "samples": event["samples"], "rows": len(gyro), "gyro": gyro.tobytes(),
            "t_s": np.asarray(columns["t_s"]).tobytes(),
        }
    return summary


def test_kill_9_at_random_points_then_resume_matches_an_uninterrupted_run(
        h: Any, tmp_path: Path, capsys, monkeypatch, fork_server: ForkServer) -> None:
    """The killed runs are forked from the warm fork server (each a process of its own,
    killed by its pid from here; no interpreter start and imports, ~2.5 s of CPU a trial);
    no report here draws its figures (only results.json and the samples are compared)."""
    without_report_figures(monkeypatch)
    procedure = h.write_procedure(tmp_path)
    reference = tmp_path / "reference"
    assert main(["run", str(procedure), "--sim", "--out", str(reference), "--seed", "5"]) == EXIT_OK
    expected = step_summary(reference)
    assert set(expected) == {s for s in h.SMALL_PLAN if ".sf." in s or s.endswith("static")}

    rng = random.Random(20240607)
    # Stratified: one random kill point in each quarter of the ~1 s the run takes after
    # preflight, so soaks, dwells and the report are all hit across the trials.
    delays_s = [(trial + rng.random()) * 0.25 for trial in range(4)]
    killed_in: list[str] = []
    for trial, delay_s in enumerate(delays_s):
        out = tmp_path / f"killed{trial}"
        proc = fork_server.start(["run", str(procedure), "--sim", "--out", str(out),
                                  "--seed", "5"], {}, tmp_path / f"killed{trial}.err",
                                 figures=False)
        try:
            wait_for_event(out, "preflight_ok", proc)
            time.sleep(delay_s)
            os.kill(proc.pid, signal.SIGKILL)
        finally:
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        log = h.events(out)   # reading verifies the chain up to any torn last line
        killed_in.append(f"{delay_s:.2f}s→#{log[-1]['seq']} {log[-1]['event']}")
        if h.manifest(out)["state"] == "running":
            assert "interrupted (process gone; resumable)" in status_text(out, capsys)
        capsys.readouterr()
        assert main(["resume", str(out)]) == EXIT_OK, killed_in[-1]
        list(read_journal(out / "journal.jsonl"))
        torn = out / "journal.torn"
        if torn.exists():   # set aside by design; what was torn never joins the chain
            assert torn.read_bytes().endswith(b"\n")
        assert h.completed_ids(out) == list(h.SMALL_PLAN) or \
            sorted(h.completed_ids(out)) == sorted(h.SMALL_PLAN)
        assert len(h.completed_ids(out)) == len(h.SMALL_PLAN)   # no step completed twice
        h.assert_chunks_intact(out)
        got = step_summary(out)
        assert set(got) == set(expected)
        for step_id, ref in expected.items():
            assert got[step_id]["samples"] == ref["samples"] == got[step_id]["rows"], step_id
            assert got[step_id]["t_s"] == ref["t_s"], (step_id, killed_in[-1])
            assert got[step_id]["gyro"] == ref["gyro"], (step_id, killed_in[-1])
        compare_results(reference, out)
    print("kill -9 points:", "; ".join(killed_in))


def compare_results(reference: Path, resumed: Path) -> None:
    """When the report builder wrote results.json, the scale factors are the same numbers."""
    import json

    ref_path, got_path = reference / "report" / "results.json", resumed / "report" / "results.json"
    assert ref_path.exists() == got_path.exists()
    if not ref_path.exists():
        return
    ref = json.loads(ref_path.read_text())["scale_factor"]
    got = json.loads(got_path.read_text())["scale_factor"]
    assert [r["temp_c"] for r in ref] == [g["temp_c"] for g in got]
    for r, g in zip(ref, got, strict=True):
        assert (g["sf"], g["u"]) == (r["sf"], r["u"])
