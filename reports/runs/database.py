"""The lab's runs as one DuckDB database, built over run folders where they lie.

Nothing is copied: ``runs`` and ``metrics`` are small tables from each
folder's manifest and ``report/results.json``, and ``samples`` is a view that
reads the folders' Parquet chunks in place (``read_parquet`` over their
paths), so plain SQL reaches every sample of every indexed run. Indexing is
idempotent: a folder indexed again replaces its rows (keyed by run id).

Only the chunks of each step's counted attempt are in the view (the record's
one attempt rule, ``record.samples.RunSamples``): a step cut by a fault or a
kill and run again keeps its first attempt's chunks on disk, journaled with
their hashes, and a query over every file would count those samples twice.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import duckdb

from gyrocal.record.journal import JournalError
from gyrocal.record.plan_record import (
    PlanRecord,
    PlanRecordError,
    PlanRecordMissing,
    load_plan_record,
)
from gyrocal.record.run_folder import RunFolderError
from gyrocal.record.samples import RunSamples
from gyrocal.reports.runs.metrics import metric_values

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    run_id VARCHAR PRIMARY KEY, run_dir VARCHAR, serial VARCHAR, model VARCHAR,
    procedure VARCHAR, station VARCHAR, state VARCHAR, mode VARCHAR, seed BIGINT,
    started_at TIMESTAMP, ended_at TIMESTAMP, has_results BOOLEAN, indexed_at TIMESTAMP);
CREATE TABLE IF NOT EXISTS metrics (
    run_id VARCHAR, serial VARCHAR, started_at TIMESTAMP, metric VARCHAR,
    value DOUBLE, u DOUBLE, expanded_u DOUBLE);  -- GUM u and U (DuckDB names ignore case)
"""


class RunsDatabaseError(Exception):
    """A folder or database the command cannot use (names it)."""


@dataclass(frozen=True)
class IndexSummary:
    indexed: int
    with_results: int
    chunks: int


def find_run_folders(roots: list[Path]) -> list[Path]:
    found: list[Path] = []
    for root in roots:
        if not root.is_dir():
            raise RunsDatabaseError(f"{root}: not a folder")
        if (root / "manifest.json").is_file():
            found.append(root.resolve())
            continue
        found.extend(p.parent.resolve() for p in sorted(root.rglob("manifest.json")))
    return sorted(set(found))


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except ValueError as exc:
        raise RunsDatabaseError(f"{path}: not valid JSON ({exc})") from None
    return data if isinstance(data, dict) else None


def _plan(folder: Path) -> PlanRecord | None:
    """The run's plan record (the record's one reader), None when the run wrote none."""
    try:
        return load_plan_record(folder)
    except PlanRecordMissing:
        return None
    except PlanRecordError as exc:
        raise RunsDatabaseError(str(exc)) from None


def connect(db_path: Path) -> duckdb.DuckDBPyConnection:
    con = duckdb.connect(str(db_path))
    con.execute(SCHEMA)
    return con


def index_runs(db_path: Path, roots: list[Path]) -> IndexSummary:
    folders = find_run_folders(roots)
    con = connect(db_path)
    try:
        with_results = 0
        for folder in folders:
            manifest = _read_json(folder / "manifest.json") or {}
            results = _read_json(folder / "report" / "results.json")
            run_id = str(manifest.get("run_id") or folder.name)
            uut = (results or {}).get("unit_under_test") or manifest.get("unit_under_test") or {}
            serial = str(uut.get("serial", "")) if isinstance(uut, dict) else ""
            plan = _plan(folder)
            if not serial and plan is not None:
                serial = str(plan.unit_under_test.get("serial", ""))
            started = _timestamp(manifest.get("started_at"))
            con.execute("DELETE FROM runs WHERE run_id = ?", [run_id])
            con.execute("DELETE FROM metrics WHERE run_id = ?", [run_id])
            con.execute(
                "INSERT INTO runs VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, current_timestamp::TIMESTAMP)",
                [run_id, str(folder), serial, str(uut.get("model", "")) if isinstance(uut, dict)
                 else "", plan.procedure_name if plan is not None else "",
                 str(manifest.get("station_name") or ""), str(manifest.get("state") or ""),
                 str(manifest.get("mode") or ""), manifest.get("seed") if isinstance(
                     manifest.get("seed"), int) else None,
                 started, _timestamp(manifest.get("ended_at")), results is not None])
            if results is not None:
                with_results += 1
                con.executemany("INSERT INTO metrics VALUES (?, ?, ?, ?, ?, ?, ?)", [
                    [run_id, serial, started, m.metric, m.value, m.u, m.U]
                    for m in metric_values(results)])
        chunks = _refresh_samples_view(con)
        return IndexSummary(len(folders), with_results, chunks)
    finally:
        con.close()


def counted_chunk_files(run_dir: Path) -> list[str]:
    """The chunk files of every step's counted attempt (superseded attempts left out).

    A folder indexed earlier and since moved or deleted has no samples to offer (its
    ``runs`` and ``metrics`` rows stay: they were read when it was there)."""
    if not (run_dir / "manifest.json").is_file():
        return []
    try:
        samples = RunSamples(run_dir)
    except (JournalError, RunFolderError) as exc:
        raise RunsDatabaseError(f"{run_dir}: journal unreadable, its samples cannot be "
                                f"indexed: {exc}") from None
    return [str(p) for step_id in samples.logged for p in samples.chunk_paths(step_id)]


def _refresh_samples_view(con: duckdb.DuckDBPyConnection) -> int:
    """``samples``: every indexed run's counted chunks, read in place, with run_id and step_id."""
    dirs = [row[0] for row in con.execute("SELECT run_dir FROM runs ORDER BY run_dir").fetchall()]
    files = [f for d in dirs for f in counted_chunk_files(Path(d))]
    con.execute("DROP VIEW IF EXISTS samples")
    if not files:
        return 0
    listing = ", ".join("'" + f.replace("'", "''") + "'" for f in files)
    con.execute(f"""
        CREATE VIEW samples AS
        SELECT r.run_id, r.serial, split_part(s.filename, '/', -2) AS step_id, s.* EXCLUDE (filename)
        FROM read_parquet([{listing}], filename = true) s
        JOIN runs r ON starts_with(s.filename, r.run_dir || '/')""")
    return len(files)


def _timestamp(text: Any) -> str | None:
    """The manifest's ``%Y-%m-%dT%H:%M:%S%z`` as a UTC timestamp (the database keeps UTC)."""
    if not isinstance(text, str) or not text:
        return None
    try:
        parsed = dt.datetime.strptime(text, "%Y-%m-%dT%H:%M:%S%z")
    except ValueError:
        return None
    return parsed.astimezone(dt.timezone.utc).replace(tzinfo=None).isoformat()


def list_runs(db_path: Path) -> list[tuple]:
    con = _open_existing(db_path)
    try:
        return con.execute("""SELECT run_id, serial, procedure, state, started_at, has_results,
                              run_dir FROM runs ORDER BY started_at, run_id""").fetchall()
    finally:
        con.close()


def history(db_path: Path, serial: str, model: str | None = None
            ) -> tuple[str, list[str], list[dict[str, Any]]]:
    """(the unit's model, metric names, one row per run with value/u/U per metric), oldest
    first. A unit is its model and serial together: two gyros of different models may share
    a serial, and one's calibrations are not the other's history. With several models for
    ``serial`` and no ``model``, :class:`RunsDatabaseError` names them."""
    con = _open_existing(db_path)
    try:
        models = [row[0] for row in con.execute(
            "SELECT DISTINCT model FROM runs WHERE serial = ? AND has_results ORDER BY model",
            [serial]).fetchall()]
        if model is None and len(models) > 1:
            raise RunsDatabaseError(
                f"{serial} is the serial of {len(models)} units (models "
                + ", ".join(repr(m) for m in models) + "); give --model MODEL")
        model = model if model is not None else (models[0] if models else "")
        rows = con.execute("""
            SELECT r.run_id, r.started_at, m.metric, m.value, m.u, m.expanded_u
            FROM runs r JOIN metrics m USING (run_id)
            WHERE r.serial = ? AND r.model = ? ORDER BY r.started_at, r.run_id""",
                           [serial, model]).fetchall()
    finally:
        con.close()
    runs: dict[str, dict[str, Any]] = {}
    metrics: list[str] = []
    for run_id, started, metric, value, u, U in rows:  # noqa: N806 - GUM's symbol
        entry = runs.setdefault(run_id, {"run_id": run_id, "started_at": started, "values": {}})
        entry["values"][metric] = (value, u, U)
        if metric not in metrics:
            metrics.append(metric)
    return model, metrics, list(runs.values())


def run_dir_of(db_path: Path, run: str) -> Path:
    """A run folder given as a path, or as a run id the database knows."""
    if (Path(run) / "manifest.json").is_file():
        return Path(run)
    if Path(db_path).is_file():
        con = _open_existing(db_path)
        try:
            row = con.execute("SELECT run_dir FROM runs WHERE run_id = ?", [run]).fetchone()
        finally:
            con.close()
        if row:
            return Path(row[0])
    raise RunsDatabaseError(f"{run}: neither a run folder nor a run id in {db_path}")


def _open_existing(db_path: Path) -> duckdb.DuckDBPyConnection:
    if not Path(db_path).is_file():
        raise RunsDatabaseError(f"{db_path}: no runs database; build it with "
                                f"`gyrocal runs index DIR...`")
    return connect(db_path)
