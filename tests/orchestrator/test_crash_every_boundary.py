"""kill -9 at every record boundary of a short run, then ``resume``, then ``verify``.

Random kill points (test_run_interrupts.py) sample the run; this test walks
all of its boundaries. The run makes itself die by SIGKILL
(``GYROCAL_CRASH_AT``, record/crash.py) right before each
journal line K is written, right after each is fsynced, and inside each
atomic file write (temporary file complete, not renamed). After each kill:
``gyrocal resume`` must exit 0, ``gyrocal verify --key`` must pass, every
line the killed run wrote must still open the history byte for byte, each
plan step must be completed exactly once, its counted attempt holding the
uninterrupted run's samples value for value in every column and results.json
the same numbers (the run is seeded: a resumed dry run equals the
uninterrupted one, engine.Rehearsal), and whatever the kill left unrecorded
(a chunk, a temporary file) must be set aside in ``orphans/``, named by
verify, and read by nothing.

The killed runs are forked from this (already warm) test process, so a kill
point costs a simulator start and a fraction of a second of simulated time,
not an interpreter start.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main
from gyrocal.record.crash import CRASH_AT_ENV
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.samples import read_chunks
from gyrocal.record.signing import generate_key_pair
from gyrocal.reports.verify import verify_run_folder
from tests.support.fork_server import ForkServer
from tests.support.short_run import SHORT_PLAN, short_procedure, without_report_figures

# a hang guard, not a speed target: the sweep is ~1.5 min of CPU, and a shared 2-core host
# running the suite on both cores gives it a fraction of one
pytestmark = [pytest.mark.timeout(1200), pytest.mark.slow]


@pytest.fixture(autouse=True)
def _no_figures(monkeypatch):
    """Every report this module's own process builds (the reference runs, the resumes) has
    no figures: what is compared is the record and results.json, which no figure feeds, and
    the figures are drawn before the page's atomic write, so every kill point is where it
    was. A short run's figures are ~0.86 of its 1.06 s CPU (measured, the run's other work 0.19 s)."""
    without_report_figures(monkeypatch)

def killed_run(server: ForkServer, procedure: Path, out: Path, crash_at: str,
               env: dict[str, str] | None = None) -> int:
    """A forked ``gyrocal run --sim`` that kills itself at ``crash_at``; returns its wait status.

    Its report page gets no figures (``ForkServer.run``): what is checked after a kill is
    the record, and a figure is drawn before the page's atomic write, so every kill point
    is where it was."""
    out.parent.mkdir(parents=True, exist_ok=True)
    return server.run(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                       "--allow-outside-paths"], {CRASH_AT_ENV: crash_at, **(env or {})},
                      out.parent / f"{out.name}.err", figures=False)


#: results.json keys that name the run, a wall time or a loopback address, or count the
#: history (the journal block: its events, chunks, the hash over every chunk; the
#: signature over the run identity and the journal's head)
RESULTS_FREE = {"run_id", "started_at", "steps_started_at", "steps_done_at", "ended_at",
                "report_built_at", "address", "journal", "signature"}


def step_data(run: Path) -> dict[str, dict[str, bytes]]:
    """step_id → its counted attempt's columns, each decoded to the bytes of its array."""
    folder = RunFolder(run)
    out = {}
    for event in folder.journal_events():
        if event.get("event") != "step_completed" or not event.get("chunks"):
            continue
        columns = read_chunks(folder.path, event["chunks"])
        out[event["step_id"]] = {name: np.asarray(columns[name]).dtype.str.encode()
                                 + np.asarray(columns[name]).tobytes() for name in columns}
    return out


def results_numbers(run: Path) -> dict:
    """results.json without what names the run or counts its history (RESULTS_FREE)."""
    def without(value):
        if isinstance(value, dict):
            return {k: without(v) for k, v in value.items() if k not in RESULTS_FREE}
        return [without(v) for v in value] if isinstance(value, list) else value
    return without(json.loads((run / "report" / "results.json").read_text()))


def boundaries(reference: Path) -> list[str]:
    """Every kill point of the run: before and after each journal line, inside each atomic write."""
    lines = (reference / "journal.jsonl").read_bytes().count(b"\n")
    atomic_writes = int((reference.parent / "atomic-writes").read_text())
    return ([f"before:{k}" for k in range(1, lines + 1)] + [f"after:{k}" for k in range(1, lines + 1)]
            + [f"tmp:{n}" for n in range(1, atomic_writes + 1)])


def reference_run(procedure: Path, out: Path) -> None:
    """The uninterrupted run, counting its atomic writes (the tmp: kill points)."""
    import gyrocal.record.atomic as atomic

    calls = []
    original = atomic.at_atomic_write
    atomic.at_atomic_write = lambda: calls.append(1)
    try:
        assert main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5",
                     "--allow-outside-paths"]) == EXIT_OK
    finally:
        atomic.at_atomic_write = original
    (out.parent / "atomic-writes").write_text(str(len(calls)))


def test_kill_at_every_boundary_resumes_to_a_history_that_verifies(h, tmp_path, monkeypatch,
                                                                     capsys, fork_server):
    keys = generate_key_pair(tmp_path / "keys")
    procedure = short_procedure(h, tmp_path)
    reference = tmp_path / "ref" / "run"
    reference.parent.mkdir()
    monkeypatch.setenv("GYROCAL_SIGNING_KEY", str(keys.private))   # run, resume: signed
    reference_run(procedure, reference)
    assert h.completed_ids(reference) == list(SHORT_PLAN)
    expected = (step_data(reference), results_numbers(reference))
    points = boundaries(reference)
    assert len(points) > 50, points
    outcomes: dict[str, int] = {"killed": 0, "orphans": 0, "closed_on_resume": 0, "no_folder": 0}
    for point in points:
        _kill_resume_verify(fork_server, h, procedure, tmp_path / "k" / point.replace(":", "-"),
                            point, keys, expected, outcomes, capsys)
    print("kill points:", len(points), outcomes)
    # the boundaries that matter were really hit: a chunk on disk before its line, a
    # temporary file, and a run cut between run_completed and run_closed
    assert outcomes["orphans"] >= 3 and outcomes["closed_on_resume"] >= 1


def _kill_resume_verify(server, h, procedure, out, point, keys, expected, outcomes, capsys):
    """One kill point: killed at ``point``, resumed, verified, compared with the reference."""
    status = killed_run(server, procedure, out, point,
                        {"GYROCAL_SIGNING_KEY": str(keys.private)})
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (
        point, status, (out.parent / f"{out.name}.err").read_text())
    outcomes["killed"] += 1
    capsys.readouterr()
    if not (out / "manifest.json").is_file():
        # Killed inside the very first write (the manifest's): no run folder exists yet,
        # and resume says so (bad input, exit 2) instead of inventing one.
        assert main(["resume", str(out)]) == EXIT_BAD_INPUT, point
        assert "not a run folder" in capsys.readouterr().err
        outcomes["no_folder"] += 1
        return
    before = (out / "journal.jsonl").read_bytes() if (out / "journal.jsonl").exists() else b""
    before = before[: before.rfind(b"\n") + 1]          # a torn tail is set aside, not kept
    assert main(["resume", str(out)]) == EXIT_OK, (point, capsys.readouterr())
    assert (out / "journal.jsonl").read_bytes().startswith(before), point
    audit = verify_run_folder(out, public_key=keys.public)
    assert audit.ok, (point, audit.failure)
    assert h.completed_ids(out) == list(SHORT_PLAN), point         # each step once
    got = step_data(out)
    assert set(got) == set(expected[0]), point
    for step_id, columns in expected[0].items():         # equal to the uninterrupted run
        assert got[step_id] == columns, (point, step_id,
                                         [c for c in columns if got[step_id].get(c) != columns[c]])
    assert results_numbers(out) == expected[1], point
    events = h.events(out)
    orphans = [e for e in events if e["event"] == "orphan_set_aside"]
    counted = {c for e in events if e["event"] == "step_completed" for c in e.get("chunks", [])}
    for orphan in orphans:
        assert (out / orphan["moved_to"]).is_file() and orphan["moved_to"].startswith("orphans/")
        assert orphan["path"] not in counted and orphan["moved_to"] not in counted
        assert any(orphan["moved_to"] in line for line in audit.orphans), point
    assert not [p for p in out.rglob("*.tmp") if "orphans" not in p.parts], point
    outcomes["orphans"] += bool(orphans)
    outcomes["closed_on_resume"] += any(e.get("closed_by") == "resume" for e in events)


def test_the_killed_chunk_is_named_and_never_counted(h, tmp_path, capsys, fork_server):
    """Killed right before the first chunk_written: the chunk is on disk and unrecorded."""
    procedure = short_procedure(h, tmp_path)
    reference = tmp_path / "ref"
    assert main(["run", str(procedure), "--sim", "--out", str(reference), "--seed", "5",
                 "--allow-outside-paths"]) == EXIT_OK
    first_chunk = next(e for e in h.events(reference) if e["event"] == "chunk_written")
    out = tmp_path / "killed"
    status = killed_run(fork_server, procedure, out, f"before:{first_chunk['seq']}")
    assert os.WTERMSIG(status) == signal.SIGKILL
    assert (out / first_chunk["path"]).is_file()
    failed = verify_run_folder(out)
    assert not failed.ok and "INCOMPLETE" in failed.failure
    assert main(["resume", str(out)]) == EXIT_OK
    orphan = next(e for e in h.events(out) if e["event"] == "orphan_set_aside")
    assert orphan["path"] == first_chunk["path"]
    assert orphan["moved_to"] == f"orphans/{first_chunk['path']}"
    assert "never journaled" in orphan["reason"]
    capsys.readouterr()
    assert main(["verify", str(out)]) == EXIT_OK
    text = capsys.readouterr().out
    assert f"set aside, never counted: {first_chunk['path']} → orphans/{first_chunk['path']}" in text
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["journal"]["chunks"] == len([e for e in h.events(out)
                                                if e["event"] == "chunk_written"])


@pytest.mark.parametrize("command", ["report", "certificate"])
def test_a_killed_report_rebuild_or_certificate_resumes_to_a_verified_run(h, tmp_path, command,
                                                                           monkeypatch, capsys,
                                                                           fork_server):
    """Every boundary of ``gyrocal report`` / ``certificate`` on a closed, signed run.

    The rebuilt report pages have no figures (here and in the forked commands): the
    figures are drawn before the page's atomic write, so the kill points are the same."""
    import shutil

    keys = generate_key_pair(tmp_path / "keys")
    monkeypatch.setenv("GYROCAL_SIGNING_KEY", str(keys.private))
    procedure = short_procedure(h, tmp_path)
    closed = tmp_path / "closed"
    assert main(["run", str(procedure), "--sim", "--out", str(closed), "--seed", "5",
                 "--allow-outside-paths"]) == EXIT_OK
    lines = len(h.events(closed))
    # its atomic writes (results.json and report.html, or the PDF) and its two journal
    # lines (report_written or certificate_written, then the seal), before and after each
    points = [f"tmp:{n}" for n in (1, 2)] + [f"{when}:{lines + k}" for k in (1, 2)
                                              for when in ("before", "after")]
    env = {"GYROCAL_SIGNING_KEY": str(keys.private)}
    for point in points:
        run = tmp_path / point.replace(":", "-")
        shutil.copytree(closed, run)
        status = fork_server.run([command, str(run)], {CRASH_AT_ENV: point, **env},
                                 tmp_path / f"{point}.err", figures=False)
        killed = os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL
        assert killed or (command == "certificate" and point == "tmp:2"), (point, status)
        capsys.readouterr()
        assert main(["resume", str(run)]) == EXIT_OK, (point, capsys.readouterr())
        assert "run already complete" in capsys.readouterr().out
        audit = verify_run_folder(run, public_key=keys.public)
        assert audit.ok, (point, audit.failure)
        assert not [p for p in run.rglob("*.tmp") if "orphans" not in p.parts], point


def test_a_power_cut_mid_line_resumes_and_verify_expects_the_torn_tail(h, tmp_path, capsys,
                                                                       fork_server):
    """A torn last line (the one thing SIGKILL cannot make: a write cut by the power)."""
    procedure = short_procedure(h, tmp_path)
    out = tmp_path / "run"
    status = killed_run(fork_server, procedure, out, "after:12")
    assert os.WTERMSIG(status) == signal.SIGKILL
    with open(out / "journal.jsonl", "ab") as journal:
        journal.write(b'{"event":"step_completed","step_id":"T01.sf')     # cut mid-line
    assert main(["resume", str(out)]) == EXIT_OK
    events = h.events(out)
    torn = [e for e in events if e["event"] == "torn_tail_set_aside"]
    assert len(torn) == 1 and torn[0]["seq"] == 13          # named right after the last whole line
    assert h.completed_ids(out) == list(SHORT_PLAN)
    audit = verify_run_folder(out)
    assert audit.ok, audit.failure
    assert "torn journal tail → journal.torn" in audit.orphans
    (out / "journal.torn").write_bytes(b"edited\n")
    assert "journal.torn" in verify_run_folder(out).failure
