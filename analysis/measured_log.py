"""Read a measured log (CSV or Parquet, gyro-model.md "Measured log") or a run folder.

A QA number is only as good as the rows behind it, so nothing is dropped
quietly: a missing column, a non-finite value or a time that does not
increase is an error naming the file, the row (1-based data row, as a
spreadsheet shows it counting the header as row 1) and the column.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from gyrocal.analysis.log_contract import (
    LogFormatError,
    check_parquet_schema,
    check_time,
    check_values,
)
from gyrocal.inputs import check_text_head, require_regular_file
from gyrocal.record.samples import RunSamples

__all__ = ["LogFormatError", "MeasuredLog", "read_measured_log", "validate_columns"]

REQUIRED_COLUMNS = ("t_s", "table_rate_dps", "chamber_temp_c", "gyro")
OPTIONAL_COLUMNS = ("sensor_temp_c", "table_angle_deg", "field_t")


@dataclass
class MeasuredLog:
    source: str
    t_s: np.ndarray
    table_rate_dps: np.ndarray
    chamber_temp_c: np.ndarray
    gyro: np.ndarray
    sensor_temp_c: np.ndarray | None = None
    table_angle_deg: np.ndarray | None = None
    #: magnetic field along the sensitive axis, T (read by the magnetic_sensitivity effect)
    field_t: np.ndarray | None = None
    #: per-sample segment label (a run folder's step id), or None for a plain log
    segment: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def sample_rate_hz(self) -> float:
        """Read from ``t_s`` (median spacing, robust to gaps between run-folder steps)."""
        if len(self) < 2:
            raise LogFormatError(f"{self.source}: fewer than 2 rows; no sample rate")
        return float(1.0 / np.median(np.diff(self.t_s)))


def _read_columns(path: Path) -> tuple[dict[str, np.ndarray], int]:
    """Columns as float arrays and the row offset of the first data row (for messages)."""
    suffix = path.suffix.lower()
    # Through the input layer: a FIFO, a device or a binary file is refused by name,
    # never read forever and never echoed.
    if suffix in (".csv", ".txt"):
        check_text_head(path, what="a CSV log")
    else:
        require_regular_file(path)
    if suffix in (".parquet", ".pq"):
        return _read_parquet(path), 1
    if suffix in (".csv", ".txt"):
        return _read_csv(path), 2
    raise LogFormatError(f"{path}: unknown log format {suffix!r}; use .csv or .parquet")


def _read_parquet(path: Path) -> dict[str, np.ndarray | None]:
    """The contract's columns, their types checked on the schema before a value is converted."""

    contract = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
    try:
        schema = pq.read_schema(path)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises many types for bad files
        raise LogFormatError(f"{path}: not a readable Parquet file: {exc}") from None
    check_parquet_schema(path, schema, list(contract))
    wanted = [name for name in contract if name in schema.names]
    try:
        table = pq.read_table(path, columns=wanted)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises many types for bad files
        raise LogFormatError(f"{path}: not a readable Parquet file: {exc}") from None
    return {name: table.column(name).to_numpy(zero_copy_only=False).astype(np.float64)
            for name in wanted}


def _read_csv(path: Path) -> dict[str, np.ndarray]:

    # utf-8-sig: a byte-order mark (spreadsheet exports write one) is not part of the
    # first column's name; csv takes quoted names ("t_s") as the names they quote.
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.reader(handle)
        try:
            header = [name.strip() for name in next(reader)]
        except StopIteration:
            raise LogFormatError(f"{path}: empty file, expected a header row") from None
        if len(set(header)) != len(header):
            dupes = sorted({h for h in header if header.count(h) > 1})
            raise LogFormatError(f"{path}: line 1: duplicate column(s) {', '.join(dupes)}")
        wanted = [i for i, name in enumerate(header) if name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
        values: list[list[float]] = [[] for _ in wanted]
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                raise LogFormatError(f"{path}: line {line_no}: empty row")
            if len(row) != len(header):
                raise LogFormatError(
                    f"{path}: line {line_no}: {len(row)} fields, the header has {len(header)}")
            for slot, i in enumerate(wanted):
                cell = row[i].strip()
                try:
                    values[slot].append(float(cell))
                except ValueError:
                    raise LogFormatError(
                        f"{path}: line {line_no}: column {header[i]}: {cell!r} is not a number"
                    ) from None
    return {header[i]: np.asarray(values[slot]) for slot, i in enumerate(wanted)}


def validate_columns(columns: dict[str, np.ndarray | None], source: str, first_row: int) -> None:
    """The log contract (``log_contract.py``): present, numeric, finite, physical, time increasing."""
    missing = [name for name in REQUIRED_COLUMNS if name not in columns]
    if missing:
        header = "line 1 (the header): " if first_row == 2 else ""   # a CSV's header row
        raise LogFormatError(f"{source}: {header}missing required column(s) {', '.join(missing)}; "
                             f"required: {', '.join(REQUIRED_COLUMNS)}")
    for name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS:
        if name not in columns:
            continue
        data = columns[name]
        if data is None:
            raise LogFormatError(f"{source}: column {name}: not numeric")
        check_values(data, source, name, first_row)
    check_time(columns["t_s"], source, "t_s", first_row)


def read_measured_log(path: str | Path) -> MeasuredLog:
    """A CSV/Parquet log, or a run folder (its completed steps, in order)."""
    path = Path(path)
    if path.is_dir():
        return read_run_folder_log(path)
    if not path.is_file():
        raise LogFormatError(f"{path}: no such file")
    columns, first_row = _read_columns(path)
    validate_columns(columns, str(path), first_row)
    return MeasuredLog(
        source=str(path),
        **{name: columns[name] for name in REQUIRED_COLUMNS},
        **{name: columns.get(name) for name in OPTIONAL_COLUMNS},
    )


def read_run_folder_log(run_dir: Path) -> MeasuredLog:
    """The samples of every completed logged step of a run folder, labelled by step id.

    Only the chunks that the journal lists for a completed attempt are used;
    chunks of bad or interrupted attempts stay on disk (nothing is deleted)
    but do not enter the analysis.
    """
    record = RunSamples(run_dir)
    steps = list(record.logged)
    if not steps:
        raise LogFormatError(f"{run_dir}: the run folder has no completed logged steps")
    # one read of every chunk (not one per step: on an overnight folder the per-step
    # copies and the per-sample label fill were half of the 10 s it took)
    data, rows = record.steps_joined(steps, optional=("status",))
    labels = np.repeat(np.array(steps, dtype=object), rows)
    status = data.pop("status", None)   # the only optional column read
    columns: dict[str, np.ndarray | None] = dict(data)
    if status is not None:
        # Samples the gyro flagged (saturated, in error) are bad data: never analysed.
        good = status == 0
        if not np.all(good):
            columns = {name: values[good] for name, values in data.items()}
            labels = labels[good]
    if np.all(np.isnan(columns["sensor_temp_c"])):
        columns["sensor_temp_c"] = None
    checked = {k: v for k, v in columns.items() if v is not None}
    validate_columns(checked, f"{run_dir} (samples)", 1)
    return MeasuredLog(
        source=str(run_dir),
        **{name: columns[name] for name in REQUIRED_COLUMNS},
        **{name: columns.get(name) for name in OPTIONAL_COLUMNS},
        segment=labels,
    )
