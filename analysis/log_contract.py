"""The measured-log contract (gyro-model.md "Measured log"), checked before any numeric code runs.

Every reader of a log (``measured_log`` for the discrepancy workflow,
``allan_sources`` for ``analyze allan``) passes its columns through here
first, so nothing reaches an FFT, a fit or a compiled kernel that could
overflow, crash or allocate without bound (issue 28: a ``t_s`` scaled by
1e300 overflowed, a Parquet ``t_s`` stored as a timestamp segfaulted once and
grew memory without end, duplicate Parquet names raised KeyError).

Checked, each naming the file, the row and the column:

* types — a Parquet column the contract names must be an integer or floating
  column; a timestamp, duration, date, text or nested column is refused by its
  type before a value is converted; duplicate column names are refused;
* finiteness — NaN and ±inf (the contract's own words);
* physical range — a finite number no instrument can give (1e308 deg/s, a
  temperature below absolute zero, a time of 1e300 s) is an error, not data;
* time — strictly increasing, with a sample spacing between
  ``MIN_SPACING_S`` and ``MAX_SPACING_S``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa

from gyrocal.errors import BadInput


class LogFormatError(BadInput, ValueError):
    """The measured log cannot be used as it is; the message names file, row and column."""


@dataclass(frozen=True)
class ColumnRange:
    """The values a contract column can physically hold (inclusive), and why."""

    low: float
    high: float
    unit: str
    why: str


#: The contract's columns and what is physical for each. Generous: a limit here is
#: never a calibration tolerance, only the line beyond which a number is not data.
CONTRACT_RANGES: dict[str, ColumnRange] = {
    "t_s": ColumnRange(-1e10, 1e10, "s", "±1e10 s (317 years) covers any epoch"),
    "table_rate_dps": ColumnRange(-1e5, 1e5, "deg/s", "no rate table turns faster"),
    "chamber_temp_c": ColumnRange(-273.15, 1000.0, "°C", "absolute zero to 1000 °C"),
    "sensor_temp_c": ColumnRange(-273.15, 1000.0, "°C", "absolute zero to 1000 °C"),
    "gyro": ColumnRange(-1e12, 1e12, "output units", "no gyro output (LSB, V, deg/h) is larger"),
    "table_angle_deg": ColumnRange(-1e12, 1e12, "deg", "a turn per microsecond for years"),
    "field_t": ColumnRange(-100.0, 100.0, "T", "no laboratory coil or magnet reaches 100 T"),
}
#: Any other numeric column read as a rate (``analyze allan --column``) is held to this.
OTHER_RANGE = ColumnRange(-1e12, 1e12, "", "no measured rate is larger")
#: Sample spacing bounds: 10 MHz down to one sample a day.
MIN_SPACING_S = 1e-7
MAX_SPACING_S = 86400.0


def check_parquet_schema(path: Path, schema, columns: list[str]) -> None:
    """Refuse duplicate names and non-numeric types of ``columns`` before a value is read."""

    names = list(schema.names)
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise LogFormatError(f"{path}: duplicate column name(s) {', '.join(map(repr, dupes))}; "
                             "each column must be named once")
    for name in columns:
        if name not in names:
            continue
        kind = schema.field(name).type
        if pa.types.is_integer(kind) or pa.types.is_floating(kind):
            continue
        hint = ("; store seconds as float64 (a time stamp type is not seconds from the "
                "start of the log)" if pa.types.is_temporal(kind) else "")
        raise LogFormatError(f"{path}: column {name}: type {kind} is not a number{hint}")


def check_values(values: np.ndarray, source: str, column: str, first_row: int,
                 row_offset: int = 0, line_word: str = "line", role: str | None = None) -> None:
    """Finite and physical, or an error naming the first bad row of ``column``.

    ``role`` is the contract column whose range applies when the file names it
    otherwise (``time`` read as ``t_s``).
    """
    limits = CONTRACT_RANGES.get(role or column, OTHER_RANGE)
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(values) | (values < limits.low) | (values > limits.high)
    if not bad.any():
        return
    where = np.flatnonzero(bad)
    index = int(where[0])
    value = float(values[index])
    if not np.isfinite(value):
        what = f"non-finite value {value!r}"
    else:
        what = (f"{value!r} {limits.unit} is outside {limits.low:g} … {limits.high:g} "
                f"({limits.why})").replace("  ", " ")
    raise LogFormatError(f"{source}: {line_word} {row_offset + index + first_row}: column "
                         f"{column}: {what} ({where.size} such rows)")


def check_time(t_s: np.ndarray, source: str, column: str, first_row: int,
               line_word: str = "line") -> None:
    """Strictly increasing, with a plausible spacing (values already checked finite)."""
    if t_s.size < 2:
        raise LogFormatError(f"{source}: {t_s.size} data row(s); at least 2 are needed")
    steps = np.diff(t_s)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        row = int(bad[0]) + 1
        raise LogFormatError(f"{source}: {line_word} {row + first_row}: column {column}: time "
                             f"{float(t_s[row])!r} does not increase (previous "
                             f"{float(t_s[row - 1])!r}); {column} must be strictly increasing")
    spacing_s = float(np.median(steps))
    if not MIN_SPACING_S <= spacing_s <= MAX_SPACING_S:
        raise LogFormatError(f"{source}: column {column}: median sample spacing {spacing_s:.6g} s "
                             f"is outside {MIN_SPACING_S:g} … {MAX_SPACING_S:g} s "
                             "(a time column in other units than seconds?)")
