"""A seeded dry run is reproducible bit for bit (issue 30).

Simulated time moves only with the controller's calls and every attempt's
random draws come from (seed, step id, attempt), so two runs of a shipped
procedure with one seed must write the same samples, the same journal (apart
from wall times, the hash chain that covers them, the run identity and the
loopback ports the simulators happened to get) and the same results.json
(apart from the run identity and wall times): ``tests/support/dry_run_compare.py``.

Two runs of each shipped procedure whose dry run takes seconds, one per kind
of simulated station (the single-axis STIM300, the supply with a coil and a
powered unit, the analog gyro through a SCPI DMM, the RLG through a SCPI
counter, the table's drive switched off): test_shipped_dry_runs.py, whose
reference run of a procedure also serves its kill-and-resume check. Every
shipped procedure, the long ones included, in full:
``benchmarks/check_dry_run_determinism.py`` (its table:
docs/dry-run-determinism.md). Here: what those comparisons rely on.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from gyrocal.models.seeding import attempt_seed
from tests.support.dry_run_compare import differences


def test_the_comparison_finds_a_changed_sample_journal_field_and_result(tmp_path: Path) -> None:
    """What the two-run checks rely on: a difference anywhere it looks is named."""
    runs = []
    for name, value in (("a", 1.0), ("b", 1.0 + 2**-40)):
        run = tmp_path / name
        (run / "samples" / "S1").mkdir(parents=True)
        (run / "report").mkdir()
        pq.write_table(pa.table({"gyro": np.array([0.5, value])}),
                       run / "samples" / "S1" / "attempt1-chunk00000.parquet")
        (run / "journal.jsonl").write_text(json.dumps(
            {"event": "step_completed", "wall_time": value, "samples": value}) + "\n")
        (run / "report" / "results.json").write_text(json.dumps(
            {"run": {"run_id": name, "started_at": name}, "sf": value}))
        runs.append(run)
    assert differences(*runs) == ["samples/S1/attempt1-chunk00000.parquet: column gyro",
                                  "journal line 1 (step_completed): ['samples']",
                                  "results.json .sf"]


def test_attempt_streams_differ_by_seed_step_and_attempt_and_not_by_process() -> None:
    def first_draws(seed: int, step_id: str, attempt: int) -> list[int]:
        return np.random.default_rng(attempt_seed(seed, step_id, attempt)).integers(
            0, 2**31, 4).tolist()

    reference = first_draws(7, "T01.sf.+10dps", 1)
    assert first_draws(7, "T01.sf.+10dps", 1) == reference
    others = [first_draws(8, "T01.sf.+10dps", 1), first_draws(7, "T01.sf.-10dps", 1),
              first_draws(7, "T01.sf.+10dps", 2)]
    assert all(other != reference for other in others)
    # Python's own str hash changes per process; the step id's hash must not
    code = ("import numpy as np; from gyrocal.models.seeding import attempt_seed; "
            "print(np.random.default_rng(attempt_seed(7, 'T01.sf.+10dps', 1))"
            ".integers(0, 2**31, 4).tolist())")
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True).stdout
    assert json.loads(out) == reference
