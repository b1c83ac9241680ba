"""Which writes are fsynced: every one on a station's run, none but the last on a dry run.

A power cut is what an fsync guards against and cannot be staged here, so the
fsyncs are counted (``os.fsync`` wrapped, still called); what a kill -9 leaves
is staged for real: a child process writes and kills itself with SIGKILL.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from gyrocal.record.journal import Journal, read_journal
from gyrocal.record.run_folder import SAMPLE_COLUMNS, RunFolder


@pytest.fixture
def fsyncs(monkeypatch):
    calls: list[int] = []
    real = os.fsync

    def counting(fd):
        calls.append(fd)
        real(fd)

    monkeypatch.setattr(os, "fsync", counting)
    return calls


def _folder(tmp_path, mode: str) -> RunFolder:
    procedure = tmp_path / "p.yaml"
    procedure.write_text("version: 1\n")
    return RunFolder.create(tmp_path / f"run-{mode}", procedure, None, manifest_fields={"mode": mode})


def _chunk_columns(rows: int = 10) -> dict[str, np.ndarray]:
    return {name: np.arange(rows, dtype=float) for name in SAMPLE_COLUMNS}


@pytest.mark.parametrize("mode, durable", [("station", True), ("sim", False)])
def test_a_station_run_fsyncs_every_line_and_chunk_a_dry_run_only_on_close(tmp_path, fsyncs, mode, durable):
    folder = _folder(tmp_path, mode)
    assert folder.durable is durable
    journal = folder.open_journal()
    fsyncs.clear()
    for i in range(5):
        journal.append("tick", i=i)
    folder.write_chunk("T01.static", 1, 0, _chunk_columns())
    # every line is in the file (the kernel's page cache) before append returns, either way
    assert [e.event["i"] for e in read_journal(folder.path / "journal.jsonl")] == list(range(5))
    during = len(fsyncs)
    folder.close()
    if durable:
        assert during == 5 + 2           # each line; the chunk and its folder
        assert len(fsyncs) == during     # nothing left to do on close
    else:
        assert during == 0
        assert len(fsyncs) == 1          # the journal, once, when it closes


def test_a_dry_run_journal_killed_with_sigkill_keeps_every_line_it_wrote(tmp_path):
    path = tmp_path / "journal.jsonl"
    child = textwrap.dedent(f"""
        import os, signal
        from gyrocal.record.journal import Journal
        journal = Journal({str(path)!r}, durable=False)
        for i in range(200):
            journal.append("tick", i=i)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    proc = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    events = [e.event for e in read_journal(path)]      # the chain checks too
    assert [e["i"] for e in events] == list(range(200))
    with Journal(path) as reopened:                     # and it continues without a torn tail
        reopened.append("resumed")
    assert not (tmp_path / "journal.torn").exists()
