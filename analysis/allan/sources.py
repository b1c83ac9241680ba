"""Rate records for the Allan analysis, opened without loading them: files, file sets, run folders.

`gyrocal analyze allan` is pointed at whatever a lab has: the spec's measured
log, a plain two-column export (time, rate) from another tool, a day's worth
of hourly Parquet files, or a run folder. This module finds the time and rate
columns (by the spec's names, by common names, or by position in a two-column
file — and says so plainly when the choice is ambiguous), checks that the
record is one evenly sampled stretch (across file boundaries too), and hands
the analysis a re-iterable stream of rate blocks, so a record of any length is
analysed in bounded memory.

Every problem is a :class:`~gyrocal.analysis.measured_log.LogFormatError`
naming the file, the row (1-based data row counting a header as row 1, as a
spreadsheet shows it) and the column.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from gyrocal.analysis.allan.stream import RateBlocks
from gyrocal.analysis.log_contract import (
    CONTRACT_RANGES,
    LogFormatError,
    check_parquet_schema,
    check_time,
    check_values,
)
from gyrocal.inputs import check_text_head, require_regular_file
from gyrocal.record.logged_steps import longest_hold
from gyrocal.record.plan_record import load_plan_record
from gyrocal.record.samples import RunSamples

#: Column names taken for time, in order of preference (the spec's first).
TIME_NAMES = ("t_s", "time_s", "time", "t", "timestamp", "seconds", "sec")
#: Column names taken for the rate when --column is not given (the spec's first).
RATE_NAMES = ("gyro", "rate", "rate_dps", "rate_dph", "rate_rad_s", "omega", "gyro_rate",
              "angular_rate", "w")
#: A spacing more than this × the median is a gap: the Allan deviation needs even sampling.
GAP_FACTOR = 1.5
#: Rows per batch read from a file.
BATCH_ROWS = 1 << 20


@dataclass(frozen=True)
class RateRecord:
    """A rate record ready for streaming: ``blocks()`` yields it from the start each call."""

    description: str
    column: str
    n_samples: int
    rate_hz: float
    blocks: RateBlocks


@dataclass(frozen=True)
class _Columns:
    time: str | None
    rate: str


def _pick_columns(names: list[str], column: str | None, source: str) -> _Columns:
    lowered = {n.strip().lower(): n for n in names}
    time = next((lowered[n] for n in TIME_NAMES if n in lowered), None)
    if column is not None:
        if column not in names:
            raise LogFormatError(f"{source}: column {column!r} not in the log; "
                                 f"columns: {', '.join(names)}")
        return _Columns(time, column)
    if "gyro" in names:
        return _Columns(time, "gyro")
    candidates = [lowered[n] for n in RATE_NAMES if n in lowered]
    if len(candidates) == 1:
        return _Columns(time, candidates[0])
    others = [n for n in names if n != time]
    if not candidates and time is not None and len(others) == 1:
        return _Columns(time, others[0])  # a plain two-column log: time and one rate
    if not candidates and time is None and len(names) == 2:
        return _Columns(names[0], names[1])
    listed = ", ".join(candidates or others)
    raise LogFormatError(f"{source}: which column is the rate is ambiguous ({listed}); "
                         "name it with --column")


def _csv_header(path: Path) -> list[str] | None:
    """The header's names (BOM and quotes removed, as ``csv`` reads them), or None for bare numbers."""

    with open(path, newline="", encoding="utf-8-sig", errors="replace") as handle:
        first = next(csv.reader(handle), [])
    cells = [c.strip() for c in first if c.strip()]
    if not cells:
        raise LogFormatError(f"{path}: line 1: empty; expected a header or two numbers")
    try:
        [float(c) for c in cells]
    except ValueError:
        return [c.strip() for c in first]
    return None


class _File:
    """One CSV or Parquet file of a record: its columns, row count and batched reader."""

    def __init__(self, path: Path, column: str | None) -> None:
        self.path = path
        suffix = path.suffix.lower()
        if not path.exists():
            raise LogFormatError(f"{path}: no such file")
        # Through the input layer: a FIFO or device is refused without a read, a
        # binary file named as a CSV is refused before a byte of it is echoed.
        if suffix in (".csv", ".txt", ".dat"):
            check_text_head(path, what="a CSV log")
        else:
            require_regular_file(path)
        if suffix in (".parquet", ".pq"):
            self.kind = "parquet"

            try:
                meta = pq.ParquetFile(path)
            except Exception as exc:  # noqa: BLE001 - pyarrow raises many types for bad files
                raise LogFormatError(f"{path}: not a readable Parquet file: {exc}") from None
            names = list(meta.schema_arrow.names)
            self.schema = meta.schema_arrow
            check_parquet_schema(path, self.schema, [])      # duplicate names, before any use
            self.rows = int(meta.metadata.num_rows)
            self.first_row = 2  # as a spreadsheet export of it would show, header = row 1
        elif suffix in (".csv", ".txt", ".dat"):
            self.kind = "csv"
            header = _csv_header(path)
            self.header = header is not None
            names = header if header is not None else ["time", "rate"]
            if len(set(names)) != len(names):
                dupes = sorted({n for n in names if names.count(n) > 1})
                raise LogFormatError(f"{path}: line 1: duplicate column name(s) "
                                     f"{', '.join(map(repr, dupes))}")
            self.rows = -1  # counted in the first pass
            self.first_row = 2 if self.header else 1
        else:
            raise LogFormatError(f"{path}: unknown log format {suffix!r}; use .csv or .parquet")
        self.names = names
        self.columns = _pick_columns(names, column, str(path))
        if self.kind == "parquet":    # types of what will be read, before a value is converted
            check_parquet_schema(path, self.schema, [self.columns.rate, self.columns.time or "",
                                                     *self.contract_columns()])

    def contract_columns(self) -> list[str]:
        """The measured-log contract's columns this file also carries (checked on the first pass)."""
        chosen = {self.columns.rate, self.columns.time}
        return [n for n in CONTRACT_RANGES if n in self.names and n not in chosen]

    def batches(self, with_time: bool, extra: tuple[str, ...] = ()
                ) -> Iterator[tuple[np.ndarray | None, np.ndarray, dict[str, np.ndarray]]]:
        """(time, rate, {extra column: values}) float64 batches in order; time None unless asked."""
        wanted = [self.columns.rate] + ([self.columns.time] if with_time and self.columns.time
                                        else []) + list(extra)
        if self.kind == "parquet":

            reader = pq.ParquetFile(self.path)
            for batch in reader.iter_batches(batch_size=BATCH_ROWS, columns=wanted):
                yield self._arrays(batch, wanted, with_time)
            return

        # the names as csv read them (no BOM, no quotes); the header line itself skipped
        read = pcsv.ReadOptions(block_size=1 << 24, column_names=self.names,
                                skip_rows=1 if self.header else 0)
        convert = pcsv.ConvertOptions(include_columns=wanted,
                                      column_types={n: pa.float64() for n in wanted})
        try:
            reader = pcsv.open_csv(self.path, read_options=read, convert_options=convert)
            for batch in reader:
                yield self._arrays(batch, wanted, with_time)
        except pa.ArrowInvalid as exc:
            raise LogFormatError(self._locate_bad_cell(wanted, exc)) from None

    def _arrays(self, batch, wanted: list[str], with_time: bool
                ) -> tuple[np.ndarray | None, np.ndarray, dict[str, np.ndarray]]:
        arrays = {name: batch.column(name).to_numpy(zero_copy_only=False).astype(np.float64)
                  for name in dict.fromkeys(wanted)}
        rate = arrays.pop(wanted[0])
        time = arrays.pop(wanted[1]) if with_time and self.columns.time else None
        return time, rate, arrays

    def _locate_bad_cell(self, wanted: list[str], exc: Exception) -> str:
        """The CSV reader says only *that* a cell is bad; find which row and column."""

        with open(self.path, newline="", encoding="utf-8-sig", errors="replace") as handle:
            reader = csv.reader(handle)
            if self.header:
                next(reader)
            names = self.names
            index = {n: names.index(n) for n in wanted if n in names}
            for line_no, row in enumerate(reader, start=self.first_row):
                for name, i in index.items():
                    cell = row[i].strip() if i < len(row) else ""
                    try:
                        float(cell)
                    except ValueError:
                        return f"{self.path}: line {line_no}: column {name}: {cell!r} is not a number"
        return f"{self.path}: not a readable CSV log: {exc}"


class _TimeChecker:
    """Checks, batch by batch, that time increases evenly across all files of a record."""

    def __init__(self) -> None:
        self.dt: float | None = None
        self.last: float | None = None

    def check(self, file: _File, row0: int, time: np.ndarray) -> None:
        if time.size == 0:
            return
        if self.dt is None and time.size >= 2:
            self.dt = float(np.median(np.diff(time)))
            if not self.dt > 0:
                raise LogFormatError(f"{file.path}: column {file.columns.time}: time does not "
                                     "increase")
        if self.dt is not None:
            steps = np.diff(time)
            first = time[0] - self.last if self.last is not None else self.dt
            low, high = self.dt / GAP_FACTOR, self.dt * GAP_FACTOR
            # two reductions in the common (clean) case; locate only when something is off
            if not (low <= first <= high) or (steps.size and not (
                    steps.min() >= low and steps.max() <= high)):
                self._fail(file, row0, time, low, high)
        self.last = float(time[-1])

    def _fail(self, file: _File, row0: int, time: np.ndarray, low: float, high: float) -> None:
        where = np.concatenate([[self.last], time]) if self.last is not None else time
        steps = np.diff(where)
        k = int(np.flatnonzero((steps < low) | (steps > high))[0])
        index = row0 + k + (0 if self.last is not None else 1)  # the offending sample
        what = "gap" if steps[k] > 0 else "time does not increase"
        raise LogFormatError(
            f"{file.path}: line {index + file.first_row} (data row {index + 1}): column "
            f"{file.columns.time}: {what}: spacing {steps[k]:.6g} s after {float(where[k])!r}, "
            f"{self.dt:.6g} s elsewhere; the Allan deviation needs one evenly sampled record "
            "(split it at the gap)")


def open_log_files(paths: list[Path], column: str | None = None,
                   rate_hz: float | None = None) -> RateRecord:
    """One record from one or more files, in the order given (a day of hourly files).

    The first pass (the record's statistics) also checks time: strictly
    increasing, evenly spaced, continuous from each file into the next. Without
    a time column the sample rate must be given.
    """
    files = [_File(Path(p), column) for p in paths]
    rate_names = {f.columns.rate for f in files}
    if len(rate_names) > 1:
        raise LogFormatError(f"{paths[0]}: the files name the rate differently "
                             f"({', '.join(sorted(rate_names))}); name it with --column")
    has_time = all(f.columns.time is not None for f in files)
    if rate_hz is None:
        if not has_time:
            missing = next(f for f in files if f.columns.time is None)
            header = "line 1 (the header): " if missing.kind == "csv" and missing.header else ""
            raise LogFormatError(f"{missing.path}: {header}no time column "
                                 f"({', '.join(TIME_NAMES)}); "
                                 "give the sample rate with --rate-hz")
        rate_hz = _rate_from_time(files[0])
    counted = {"done": False, "rows": 0}

    def blocks() -> Iterator[np.ndarray]:
        checking = has_time and not counted["done"]
        checker = _TimeChecker()
        total = 0
        for file in files:
            row0 = 0
            extra = tuple(file.contract_columns()) if checking else ()
            for time, rate, others in file.batches(with_time=checking, extra=extra):
                # the log contract first (log_contract.py): finite, physical, typed
                check_values(rate, str(file.path), file.columns.rate, file.first_row, row0)
                for name, values in others.items():
                    check_values(values, str(file.path), name, file.first_row, row0)
                if checking and time is not None:
                    check_values(time, str(file.path), file.columns.time, file.first_row, row0,
                                 role="t_s")
                    checker.check(file, row0, time)
                row0 += rate.size
                total += rate.size
                yield rate
        counted["done"] = True
        counted["rows"] = total

    n_rows = sum(f.rows for f in files) if all(f.rows >= 0 for f in files) else -1
    if n_rows < 0:  # CSV: count once (the check pass), then stream
        n_rows = sum(b.size for b in blocks())
    names = ", ".join(str(p) for p in paths[:3]) + (f" and {len(paths) - 3} more"
                                                     if len(paths) > 3 else "")
    return RateRecord(names, files[0].columns.rate, n_rows, float(rate_hz), blocks)


def _rate_from_time(file: _File) -> float:
    """1 / median spacing of the first batch, snapped to 9 significant digits when that close.

    Time stamps are sums of a float spacing (t = k·τ0 carries rounding), so the
    spacing of a 200 Hz log reads 200.00000000004 Hz; the snap keeps a log's
    result identical to the same samples analysed at their nominal rate.
    """
    for time, _, _ in file.batches(with_time=True):
        if time is not None and time.size >= 2:
            check_values(time, str(file.path), str(file.columns.time), file.first_row, role="t_s")
            check_time(time, str(file.path), str(file.columns.time), file.first_row)
            spacing = float(np.median(np.diff(time)))
            if not spacing > 0:
                raise LogFormatError(f"{file.path}: column {file.columns.time}: time does not "
                                     "increase; the sample rate cannot be read from it")
            rate = 1.0 / spacing
            snapped = float(f"{rate:.9g}")
            return snapped if abs(snapped / rate - 1.0) < 1e-9 else rate
    raise LogFormatError(f"{file.path}: fewer than 2 rows; no sample rate")


def open_run_folder(run_dir: Path, column: str | None = None) -> RateRecord:
    """The longest completed static/allan hold of a run folder, streamed from its chunks.

    Through the run record (the counted attempt, samples the gyro flagged left out, as the
    report's Allan curve reads them); the sample rate is the plan's.
    """
    record = load_plan_record(run_dir)
    run = RunSamples(run_dir)
    longest = longest_hold(record.kinds, list(run.logged.values()))
    if longest is None:
        raise LogFormatError(f"{run_dir}: no completed static or allan hold to analyse")
    step_id, name = str(longest["step_id"]), column or "gyro"
    source = f"{run_dir} step {step_id}"

    def blocks() -> Iterator[np.ndarray]:
        row0 = 0
        for values in run.blocks(step_id, name):
            check_values(values, source, name, 1, row0, line_word="sample")   # finite, physical
            row0 += values.size
            yield values

    return RateRecord(source, name, run.count(step_id), record.sample_rate_hz, blocks)


def open_record(paths: list[str | Path], column: str | None = None,
                rate_hz: float | None = None) -> RateRecord:
    """A run folder (one path that is a directory) or one or more log files."""
    as_paths = [Path(p) for p in paths]
    if len(as_paths) == 1 and as_paths[0].is_dir():
        return open_run_folder(as_paths[0], column)
    dirs = [p for p in as_paths if p.is_dir()]
    if dirs:
        raise LogFormatError(f"{dirs[0]}: a run folder is analysed on its own, not with other logs")
    return open_log_files(as_paths, column, rate_hz)
