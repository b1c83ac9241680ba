"""A seeded dry run is reproducible bit for bit (issue 30).

Simulated time moves only with the controller's calls and every attempt's
random draws come from (seed, step id, attempt), so two runs of the shipped
smoke procedure with one seed must write the same samples, the same
journal (apart from wall times, the hash chain that covers them, the run
identity and the loopback ports the simulators happened to get) and the
same results.json (apart from the run identity and wall times).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from gyrocal.cli import main
from gyrocal.models.seeding import attempt_seed

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "procedures" / "smoke.yaml"

#: journal fields that may differ between two runs of one seed
JOURNAL_FREE = {"wall_time", "ended_at", "prev_sha256", "sha256", "run_id", "identity", "address",
                "files"}
#: results.json keys that name the run or a wall time, or the loopback addresses
RESULTS_FREE = {"run_id", "started_at", "steps_started_at", "steps_done_at", "ended_at",
                "report_built_at", "first_wall_time", "last_wall_time", "address"}


def columns(run_dir: Path) -> dict[str, dict[str, np.ndarray]]:
    """Every chunk of the run, decoded to arrays, by its path in the run folder."""
    chunks = {}
    for path in sorted((run_dir / "samples").rglob("*.parquet")):
        table = pq.read_table(path)
        chunks[str(path.relative_to(run_dir))] = {
            name: table.column(name).to_numpy() for name in table.column_names}
    return chunks


def without(value, free: set[str]):
    """``value`` with the keys in ``free`` removed at every depth."""
    if isinstance(value, dict):
        return {k: without(v, free) for k, v in value.items() if k not in free}
    if isinstance(value, list):
        return [without(v, free) for v in value]
    return value


def journal(run_dir: Path) -> list[dict]:
    lines = (run_dir / "journal.jsonl").read_text().splitlines()
    return [without(json.loads(line), JOURNAL_FREE) for line in lines]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_two_runs_of_the_smoke_procedure_with_one_seed_are_identical(tmp_path: Path) -> None:
    runs = [tmp_path / "first", tmp_path / "second"]
    for out in runs:
        assert main(["run", str(SMOKE), "--sim", "--seed", "7", "--out", str(out)]) in (0, 1)
    first, second = (columns(out) for out in runs)
    assert list(first) == list(second) and len(first) >= 10
    for chunk, cols in first.items():
        assert list(cols) == list(second[chunk])
        for name, values in cols.items():
            other = second[chunk][name]
            assert values.dtype == other.dtype and values.tobytes() == other.tobytes(), (chunk, name)
    assert journal(runs[0]) == journal(runs[1])
    results = [json.loads((out / "report" / "results.json").read_text()) for out in runs]
    assert results[0]["run"]["run_id"] != results[1]["run"]["run_id"]
    assert without(results[0], RESULTS_FREE) == without(results[1], RESULTS_FREE)


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
