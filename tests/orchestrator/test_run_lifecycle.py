"""The ends of a run: signals at every phase, the safe state after the last step, resume's rules.

Signals are delivered by the run to itself at a chosen record boundary
(``GYROCAL_CRASH_AT`` with ``GYROCAL_CRASH_SIGNAL``, record/crash.py),
so every phase — connecting, each step, the safe return, the report being
written, after ``run_completed``, after ``run_closed``, after the seal — is hit
exactly, not by timing luck. Each ends in exit 3 with no traceback, and
``resume`` then leaves a history ``verify`` passes.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main
from gyrocal.record.crash import CRASH_AT_ENV, CRASH_SIGNAL_ENV
from gyrocal.reports.verify import verify_run_folder
from tests.support.fork_server import ForkServer
from tests.support.short_run import SHORT_PLAN, short_procedure, without_report_figures

pytestmark = pytest.mark.timeout(900)    # a hang guard for the sweeps on a loaded host


def signalled_run(server: ForkServer, procedure: Path, out: Path, at: str,
                  signal_name: str) -> tuple[int, str]:
    """A forked ``gyrocal run --sim`` that signals itself at ``at``; (exit code, its stderr)."""
    err_path = out.parent / f"{out.name}.err"
    out.parent.mkdir(parents=True, exist_ok=True)
    status = server.run(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                         "--allow-outside-paths"],
                        {CRASH_AT_ENV: at, CRASH_SIGNAL_ENV: signal_name}, err_path,
                        figures=False)
    assert os.WIFEXITED(status), f"{at} {signal_name}: died by signal {os.WTERMSIG(status)}"
    return os.WEXITSTATUS(status), err_path.read_text()


@pytest.mark.slow
def test_a_signal_at_every_phase_exits_3_quietly_and_resumes_to_a_verified_run(h, tmp_path,
                                                                                 capsys,
                                                                                 monkeypatch,
                                                                                 fork_server):
    without_report_figures(monkeypatch)      # figures are not the point, here nor below
    procedure = short_procedure(h, tmp_path)
    reference = tmp_path / "reference"
    assert main(["run", str(procedure), "--sim", "--out", str(reference), "--seed", "5",
                 "--allow-outside-paths"]) == EXIT_OK
    names = [e["event"] for e in h.events(reference)]
    steps_done = names.index("steps_done") + 1
    completed = names.index("run_completed") + 1
    # after every journal line (SIGINT and SIGTERM in turn), and both signals where the
    # issue saw a traceback and a -15: after run_completed, after run_closed, in the report
    points = [(f"after:{k}", "SIGINT" if k % 2 else "SIGTERM") for k in range(1, len(names) + 1)]
    points += [(f"after:{completed}", "SIGTERM" if completed % 2 else "SIGINT"),
               (f"after:{len(names)}", "SIGTERM" if len(names) % 2 else "SIGINT"),
               (f"before:{steps_done + 1}", "SIGINT"), (f"before:{steps_done + 1}", "SIGTERM")]
    for at, name in points:
        _signal_resume_verify(fork_server, h, procedure, tmp_path / "s" / f"{at.replace(':', '-')}"
                              f"-{name}", at, name, completed, capsys)


def _signal_resume_verify(server, h, procedure, out, at, name, completed, capsys):
    """One phase: signalled there, exit 3 without a traceback, resumed, verified."""
    code, err = signalled_run(server, procedure, out, at, name)
    assert code == EXIT_FAULT, (at, name, err)
    assert "Traceback" not in err, (at, name, err)
    capsys.readouterr()
    assert main(["resume", str(out)]) == EXIT_OK, (at, name, capsys.readouterr())
    audit = verify_run_folder(out)
    assert audit.ok, (at, name, audit.failure)
    assert h.completed_ids(out) == list(SHORT_PLAN), (at, name)
    if at == f"after:{completed}":
        # the close was finished before exiting: nothing for resume to close
        assert "the run is closed first" in err and "complete and closed" in err
        assert [e["event"] for e in h.events(out)].count("run_closed") == 1


def test_a_completed_run_returns_the_rig_to_its_safe_state_and_reads_it_back(
        h, tmp_path, sim_capture):
    procedure = short_procedure(h, tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                 "--allow-outside-paths"], on_sim_started=sim_capture) == EXIT_OK
    events = h.events(out)
    names = [e["event"] for e in events]
    returned = events[names.index("returned_safe")]
    assert names.index("returned_safe") < names.index("steps_done")
    assert returned["confirmed"] == {"table": True, "chamber": True}
    assert returned["actions"]["chamber"] == f"chamber setpoint {h.SAFE_SETPOINT_C:.1f} °C (read back)"
    assert returned["actions"]["table"].startswith("table stopped (read back 0.0")
    # the simulated chamber itself was asked, not only our readback: the last procedure
    # setpoint was 23.0 °C, the station's safe setpoint is 25.0 °C
    assert sim_capture.last.chamber_physics.setpoint_c == pytest.approx(h.SAFE_SETPOINT_C)
    assert sim_capture.last.table_physics.demand_dps == 0.0


def test_resume_refuses_a_fast_clock_on_real_instruments(h, tmp_path, capsys):
    """The rule run applies: --speed is for simulated stations only (exit 2, nothing moves)."""
    procedure = short_procedure(h, tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                 "--allow-outside-paths", "--inject", "table.interlock_open:always@T01.sf.+20dps"]
                ) == EXIT_FAULT
    # A run made on a real station records mode "station"; the refusal must come before
    # the folder's inputs are even compared (here nothing else about the run is real).
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["mode"] = "station"
    (out / "manifest.json").write_text(json.dumps(manifest))
    lines_before = (out / "journal.jsonl").read_bytes()
    capsys.readouterr()
    assert main(["resume", str(out), "--speed", "20"]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "--speed 20: only --sim runs can change the clock" in err
    assert (out / "journal.jsonl").read_bytes() == lines_before      # nothing was commanded
    manifest["mode"] = "sim"
    (out / "manifest.json").write_text(json.dumps(manifest))
    assert main(["resume", str(out), "--speed", "max"]) == EXIT_OK    # a dry run may


def test_a_simulated_run_says_so_in_results_report_status_and_snapshot(h, tmp_path, capsys):
    procedure = short_procedure(h, tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                 "--allow-outside-paths"]) == EXIT_OK
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["run"]["mode"] == "sim" and results["run"]["simulated"] is True
    html = (out / "report" / "report.html").read_text()
    assert 'id="simulated-banner"' in html and "SIMULATED — not a calibration" in html
    capsys.readouterr()
    assert main(["status", str(out)]) == EXIT_OK
    assert "SIMULATED run: simulated instruments, not a calibration" in capsys.readouterr().out
    assert main(["status", str(out), "--json"]) == EXIT_OK
    assert json.loads(capsys.readouterr().out)["simulated"] is True
