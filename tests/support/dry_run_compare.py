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
