"""The runs database counts each step once: the counted attempt, not the chunks it superseded.

A dry run of the short smoke procedure is killed (SIGKILL, ``GYROCAL_CRASH_AT``)
right before a dwell's ``step_completed`` is journaled — its chunk is on disk,
the step is not complete — and resumed: the dwell runs again as attempt 2 and
attempt 1's chunk stays in the folder (journaled with its hash, never
deleted). The database's ``samples`` view must hold attempt 2's rows only, the
number the record's own reader (``RunSamples``) gives; a view over every file
in ``samples/`` counts the cut attempt too.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import duckdb
import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_OK, main
from gyrocal.record.crash import CRASH_AT_ENV
from gyrocal.record.samples import RunSamples
from tests.reports.runs.test_runs_database import REPO_ROOT, short_procedure
from tests.support.short_run import without_report_figures

STEP = "T01.sf.+20dps"


def _seq_of_completion(run_dir: Path, step_id: str) -> int:
    for line in (run_dir / "journal.jsonl").read_text().splitlines():
        event = json.loads(line)
        if event["event"] == "step_completed" and event.get("step_id") == step_id:
            return int(event["seq"])
    raise AssertionError(f"{step_id} never completed in {run_dir}")


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_resumed_step_is_counted_once_in_the_samples_view(tmp_path: Path, monkeypatch) -> None:
    procedure = short_procedure(tmp_path)
    without_report_figures(monkeypatch)
    runs = tmp_path / "runs"
    args = ["run", str(procedure), "--sim", "--seed", "3"]
    reference = runs / "reference"
    assert main([*args, "--out", str(reference)]) == EXIT_OK
    cut = runs / "cut"
    killed = subprocess.run([sys.executable, "-m", "gyrocal", *args, "--out", str(cut)],
                            cwd=REPO_ROOT, capture_output=True, timeout=180,
                            env={**os.environ, CRASH_AT_ENV:
                                 f"before:{_seq_of_completion(reference, STEP)}"})
    assert killed.returncode == -signal.SIGKILL, killed.stderr.decode()[-2000:]
    assert main(["resume", str(cut)]) == EXIT_OK

    on_disk = sorted((cut / "samples" / STEP).glob("*.parquet"))
    counted = RunSamples(cut)
    assert set(counted.chunk_paths(STEP)) < set(on_disk), "the cut attempt's chunk is kept"
    rows_on_disk = sum(pq.read_metadata(p).num_rows for p in on_disk)
    rows_counted = counted.step(STEP, good_only=False).n_logged

    db = tmp_path / "runs.duckdb"
    assert main(["runs", "index", str(runs), "--db", str(db)]) == EXIT_OK
    con = duckdb.connect(str(db), read_only=True)
    try:
        by_run = dict(con.execute(
            "SELECT r.run_dir, count(*) FROM samples s JOIN runs r USING (run_id) "
            "WHERE s.step_id = ? GROUP BY r.run_dir", [STEP]).fetchall())
        steps = {row[0] for row in con.execute("SELECT DISTINCT step_id FROM samples").fetchall()}
    finally:
        con.close()
    assert rows_on_disk > rows_counted > 0
    assert by_run[str(cut.resolve())] == rows_counted
    # the uninterrupted run of the same seed logged the same dwell once
    assert by_run[str(reference.resolve())] == RunSamples(reference).step(
        STEP, good_only=False).n_logged
    assert steps == set(counted.logged)
