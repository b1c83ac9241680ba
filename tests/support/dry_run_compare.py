"""What two seeded dry runs of one procedure must share, and where they differ (issue 30).

Two runs with one seed must write the same sample chunks (bytes and dtype of
every column), the same journal apart from wall times, the hash chain that
covers them, the run identity and the loopback addresses the simulators
happened to get, and the same results.json apart from the run identity and
wall times. :func:`differences` names every place they do not, so the test
asserts an empty list and ``benchmarks/check_dry_run_determinism.py`` prints it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from gyrocal.record.run_folder import RunFolder
from gyrocal.record.samples import read_chunks

#: journal fields that may differ between two runs of one seed
JOURNAL_FREE = {"wall_time", "ended_at", "prev_sha256", "sha256", "run_id", "identity", "address",
                "files"}
#: results.json keys that name the run or a wall time, or the loopback addresses
RESULTS_FREE = {"run_id", "started_at", "steps_started_at", "steps_done_at", "ended_at",
                "report_built_at", "first_wall_time", "last_wall_time", "wall_time", "address"}


def columns(run_dir: Path) -> dict[str, dict[str, np.ndarray]]:
    """Every chunk of the run, decoded to arrays, by its path in the run folder."""
    chunks = {}
    for path in sorted((run_dir / "samples").rglob("*.parquet")):
        table = pq.read_table(path)
        chunks[str(path.relative_to(run_dir))] = {
            name: table.column(name).to_numpy() for name in table.column_names}
    return chunks


def without(value: Any, free: set[str]) -> Any:
    """``value`` with the keys in ``free`` removed at every depth."""
    if isinstance(value, dict):
        return {k: without(v, free) for k, v in value.items() if k not in free}
    if isinstance(value, list):
        return [without(v, free) for v in value]
    return value


def journal(run_dir: Path) -> list[dict]:
    lines = (run_dir / "journal.jsonl").read_text().splitlines()
    return [without(json.loads(line), JOURNAL_FREE) for line in lines]


def results(run_dir: Path) -> dict:
    return json.loads((run_dir / "report" / "results.json").read_text())


def chunk_differences(first: Path, second: Path) -> list[str]:
    """Chunks or columns present in one run only, or whose dtype or bytes differ."""
    a, b = columns(first), columns(second)
    out = [f"chunks only in one run: {sorted(set(a) ^ set(b))[:3]}"] if set(a) != set(b) else []
    for chunk in sorted(set(a) & set(b)):
        if list(a[chunk]) != list(b[chunk]):
            out.append(f"{chunk}: columns {list(a[chunk])} vs {list(b[chunk])}")
            continue
        for name, values in a[chunk].items():
            other = b[chunk][name]
            if values.dtype != other.dtype or values.tobytes() != other.tobytes():
                out.append(f"{chunk}: column {name}")
    return out


def journal_differences(first: Path, second: Path) -> list[str]:
    a, b = journal(first), journal(second)
    out = [f"journal: {len(a)} vs {len(b)} lines"] if len(a) != len(b) else []
    for index, (line_a, line_b) in enumerate(zip(a, b, strict=False)):
        if line_a != line_b:
            keys = sorted(k for k in set(line_a) | set(line_b) if line_a.get(k) != line_b.get(k))
            out.append(f"journal line {index + 1} ({line_a.get('event')}): {keys}")
    return out


def results_differences(first: Path, second: Path) -> list[str]:
    a, b = results(first), results(second)
    out = [] if a["run"]["run_id"] != b["run"]["run_id"] else ["results: one run identity"]
    return out + [f"results.json {path}" for path in _paths_differing(
        without(a, RESULTS_FREE), without(b, RESULTS_FREE), "")]


def differences(first: Path, second: Path) -> list[str]:
    """Everything the two runs' folders do not share that they must (empty: identical)."""
    return (chunk_differences(first, second) + journal_differences(first, second)
            + results_differences(first, second))


def _paths_differing(a: Any, b: Any, where: str) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        return [p for key in sorted(set(a) | set(b), key=str)
                for p in _paths_differing(a.get(key), b.get(key), f"{where}.{key}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [p for i, (x, y) in enumerate(zip(a, b, strict=True))
                for p in _paths_differing(x, y, f"{where}[{i}]")]
    return [] if a == b else [where or "."]


#: results.json keys in which a resumed run may differ from the uninterrupted one: those
#: that name the run, a wall time or a loopback address, and the journal block (its events,
#: chunks and the hash over every chunk count the interruption too)
RESUMED_RESULTS_FREE = {"run_id", "started_at", "steps_started_at", "steps_done_at", "ended_at",
                        "report_built_at", "address", "journal"}


def counted_samples(run_dir: Path) -> dict[str, tuple[int, dict[str, np.ndarray]]]:
    """step_id → (attempt, decoded columns of its counted attempt's chunks)."""
    folder = RunFolder(run_dir)
    out = {}
    for event in folder.journal_events():
        if event.get("event") == "step_completed" and event.get("chunks"):
            out[event["step_id"]] = (event["attempt"],
                                     dict(read_chunks(folder.path, event["chunks"])))
    return out


def assert_resumed_equal(out: Path, name: str, expected: dict, expected_results: dict,
                         plan: list[str], cut_step: str) -> None:
    """The run in ``out``, killed at the point called ``name`` and resumed, equals the
    uninterrupted run whose counted samples and results.json are ``expected`` and
    ``expected_results`` (engine.Rehearsal): the same steps completed once each, each
    counted attempt's columns byte for byte, results.json's numbers; ``cut_step`` (killed
    mid-way when ``name`` is "mid-step") counted on its second attempt; and the resumed
    session restored the simulated state the killed one journaled last."""
    events = RunFolder.open(out).journal_events()
    assert [e["step_id"] for e in events if e["event"] == "step_completed"] == plan, name
    got = counted_samples(out)
    assert set(got) == set(expected), name
    for step_id, (attempt, step_columns) in expected.items():
        got_attempt, got_columns = got[step_id]
        assert list(got_columns) == list(step_columns), (name, step_id)
        for column, values in step_columns.items():
            other = got_columns[column]
            assert values.dtype == other.dtype and values.tobytes() == other.tobytes(), (
                name, step_id, column)
        if name == "mid-step" and step_id == cut_step:
            # cut mid-way: run again as a new attempt, with the cut attempt's draws
            assert (attempt, got_attempt) == (1, 2), name
    got_results = results(out)
    assert got_results["run"]["run_id"] != expected_results["run"]["run_id"]
    assert (without(got_results, RESUMED_RESULTS_FREE)
            == without(expected_results, RESUMED_RESULTS_FREE)), name
    kinds = [e["event"] for e in events]
    if name == "after-run-completed":
        assert "resumed" not in kinds and kinds[-1] == "run_closed", name
    else:       # the resumed session went on from the state the killed one had journaled
        restored = [e for e in events if e["event"] == "sim_state_restored"]
        assert len(restored) == 1 and "resumed" in kinds, name
        source = next(e for e in events if e["seq"] == restored[0]["from_seq"])
        # a step that acts after its step_completed line journals its state after the act
        assert source["event"] in ("step_completed", "sim_state_saved"), name
        assert restored[0]["clock_s"] == source["sim_state"]["clock_s"], name
