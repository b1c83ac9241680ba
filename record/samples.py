"""A run's sample chunks, read: the one reader of run chunks in the product.

The report, the Allan analysis of a run folder, the discrepancy workflow's
measured log and the live page all read the Parquet chunks the engine wrote.
They go through here, so the rules stay one: only the attempt of a step that
counts (``logged_steps``) is read, samples the gyro flagged (``status != 0``)
are left out unless a reader asks for them, chunks written before a column
existed are handled once, and a chunk that cannot be read is an error naming
the file (exit 2) instead of whatever the Parquet library raised. The writer
is :meth:`RunFolder.write_chunk`; external logs (CSV/Parquet a lab brings) are
read by ``analysis/measured_log.py`` and ``analysis/allan/sources.py``.
``tests/test_layout.py`` checks no other product module imports pyarrow.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from gyrocal.record.logged_steps import completed_attempts
from gyrocal.record.run_folder import (
    OPTIONAL_SAMPLE_COLUMNS,
    SAMPLE_COLUMNS,
    RunFolder,
    RunFolderError,
)

#: The per-sample flag column: a bit set of run_folder.SAMPLE_FLAGS, 0 = good.
STATUS = "status"
#: Chunk files read side by side (Parquet decoding releases the GIL).
READ_THREADS = 2
#: Rows per block when a step is streamed (the Allan analysis of a long hold).
BLOCK_ROWS = 1 << 20


class ChunkReadError(RunFolderError):
    """A sample chunk the journal names cannot be read (names the file): the folder is damaged."""


def _damaged(path: Path, exc: BaseException) -> ChunkReadError:
    text = str(exc).strip()
    why = getattr(exc, "strerror", None) or (text.splitlines()[0] if text else type(exc).__name__)
    return ChunkReadError(f"{path}: cannot be read as a sample chunk ({why}); "
                          "the run folder is damaged")


def _open(path: Path) -> pq.ParquetFile:
    """The chunk's reader; FileNotFoundError passes (a chunk being replaced right now)."""
    try:
        return pq.ParquetFile(path)
    except FileNotFoundError:
        raise
    except (OSError, pa.ArrowException, TypeError, ValueError) as exc:
        raise _damaged(path, exc) from None


def _read(path: Path, columns: Sequence[str] | None) -> pa.Table:
    chunk = _open(path)
    names = chunk.schema_arrow.names
    wanted = names if columns is None else [n for n in dict.fromkeys(columns) if n in names]
    try:
        return chunk.read(columns=wanted)
    except (OSError, pa.ArrowException, TypeError, ValueError) as exc:
        raise _damaged(path, exc) from None


def _read_all(paths: Sequence[Path], columns: Sequence[str] | None) -> list[pa.Table]:
    if len(paths) == 1:
        return [_read(paths[0], columns)]
    with ThreadPoolExecutor(READ_THREADS) as pool:
        return list(pool.map(lambda p: _read(p, columns), paths))


def column_array(column: pa.ChunkedArray) -> np.ndarray:
    """A column as one new NumPy array, like ``column.to_numpy()`` (a copy, writable).

    pyarrow's ``to_numpy`` goes through its pandas shim, which imports pandas (and
    pyarrow.compute, dedenting every compute function's docstring): ~0.25 s of a dry run
    (``python -X importtime``) to read numbers. Integer and float columns without nulls
    (every column a run writes) are copied from their buffers; anything else is left to
    ``to_numpy``.
    """
    kind = column.type
    if not (pa.types.is_integer(kind) or pa.types.is_floating(kind)) or column.null_count:
        return column.to_numpy()
    dtype = np.dtype(kind.to_pandas_dtype())
    parts = [np.frombuffer(chunk.buffers()[1], dtype=dtype, count=len(chunk),
                           offset=chunk.offset * dtype.itemsize)
             for chunk in column.chunks if len(chunk)]
    return np.concatenate(parts) if parts else np.empty(0, dtype)


def _joined(tables: list[pa.Table]) -> dict[str, np.ndarray]:
    """Columns every table has, concatenated (older chunks lack the newer optional columns).

    Empties ``tables``: each column's chunks are released as soon as the column is
    copied out, so an overnight folder's read peaks at the chunks plus one 80 MB
    column, not at the chunks plus every joined column (the whole folder twice).
    """
    if not tables:
        return {}
    common = [n for n in tables[0].column_names if all(n in t.column_names for t in tables)]
    table = pa.concat_tables([t.select(common) for t in tables]) if len(tables) > 1 \
        else tables[0].select(common)
    tables.clear()
    joined = {}
    for name in common:
        joined[name] = column_array(table.column(name))
        table = table.drop_columns([name])
    return joined


def _good_mask(columns: Mapping[str, np.ndarray], flags: Sequence[str], rows: int) -> np.ndarray:
    good = np.ones(rows, dtype=bool)
    for name in flags:
        if name in columns:
            good &= columns[name] == 0
    return good


@dataclass(frozen=True)
class StepSamples:
    """The samples of a step's counted attempt, column by column (numpy arrays)."""

    step_id: str
    attempt: int
    columns: Mapping[str, np.ndarray]
    #: rows logged, before flagged samples were left out
    n_logged: int

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    @property
    def n(self) -> int:
        """Rows kept (good samples, unless all were asked for)."""
        return len(next(iter(self.columns.values()))) if self.columns else 0


class RunSamples:
    """The samples of one run folder: its steps' counted attempts, read on demand.

    ``events``: the journal's events when the caller has them already (else read here).
    """

    def __init__(self, run_dir: Path, events: list[dict[str, Any]] | None = None) -> None:
        self.path = Path(run_dir)
        if events is None:
            events = RunFolder.open(self.path).journal_events()
        #: step_id → the counted attempt's step_completed event, for steps that logged samples
        self.logged: dict[str, dict[str, Any]] = completed_attempts(events)

    def __contains__(self, step_id: object) -> bool:
        return step_id in self.logged

    def chunk_paths(self, step_id: str) -> list[Path]:
        return [self.path / str(rel) for rel in self.logged[step_id]["chunks"]]

    def step(self, step_id: str, columns: Sequence[str] | None = None, good_only: bool = True,
             flags: Sequence[str] = (STATUS,)) -> StepSamples:
        """A step's counted attempt: ``columns`` (None: every column its chunks all have).

        ``good_only`` leaves out the samples any of ``flags`` marks (non-zero; a flag column
        a chunk lacks marks nothing). A requested column some chunk lacks is left out:
        test with ``in``. KeyError when the step logged nothing that counts.
        """
        event = self.logged[step_id]
        read = None if columns is None else [*columns, *(flags if good_only else ())]
        data = _joined(_read_all(self.chunk_paths(step_id), read))
        rows = len(next(iter(data.values()))) if data else 0
        if good_only:
            good = _good_mask(data, flags, rows)
            if not good.all():
                data = {name: values[good] for name, values in data.items()}
            if columns is not None:
                data = {n: v for n, v in data.items() if n in columns}
        return StepSamples(step_id, int(event.get("attempt", 1)), data, rows)

    def blocks(self, step_id: str, column: str, good_only: bool = True) -> Iterator[np.ndarray]:
        """One column of a step, streamed in float64 blocks (bounded memory for a long hold)."""
        for path in self.chunk_paths(step_id):
            chunk = _open(path)
            names = chunk.schema_arrow.names
            if column not in names:
                raise ChunkReadError(f"{path}: no column {column!r} in the sample chunk; "
                                     f"columns: {', '.join(names)}")
            flags = [STATUS] if good_only and STATUS in names else []
            try:
                for batch in chunk.iter_batches(batch_size=BLOCK_ROWS, columns=[column, *flags]):
                    values = batch.column(0).to_numpy(zero_copy_only=False).astype(np.float64)
                    if flags:
                        values = values[batch.column(1).to_numpy(zero_copy_only=False) == 0]
                    yield values
            except (OSError, pa.ArrowException, TypeError, ValueError) as exc:
                raise _damaged(path, exc) from None

    def count(self, step_id: str, good_only: bool = True) -> int:
        """Samples of a step (good ones only unless asked), from the footers and status alone."""
        total = 0
        for path in self.chunk_paths(step_id):
            chunk = _open(path)
            if good_only and STATUS in chunk.schema_arrow.names:
                total += int(np.count_nonzero(column_array(_read(path, [STATUS]).column(STATUS)) == 0))
            else:
                total += chunk.metadata.num_rows
        return total

    def steps_joined(self, step_ids: Sequence[str], optional: Sequence[str] = (STATUS,)
                     ) -> tuple[dict[str, np.ndarray], list[int]]:
        """Every named step's chunks in one table (one read for a whole folder), and the rows
        each step gave. Of the optional columns only those every chunk has are read."""
        return read_chunk_groups(self.path, [self.logged[s]["chunks"] for s in step_ids],
                                 tuple(optional))


def samples(run_dir: Path, step_id: str, good_only: bool = True,
            columns: Sequence[str] | None = None) -> StepSamples:
    """A step's counted attempt of a run folder (see :meth:`RunSamples.step`)."""
    return RunSamples(run_dir).step(step_id, columns, good_only)


def read_chunk_groups(run_dir: Path, groups: Sequence[Sequence[str]],
                      optional: tuple[str, ...] = OPTIONAL_SAMPLE_COLUMNS,
                      ) -> tuple[dict[str, np.ndarray], list[int]]:
    """Every group's chunks (relative paths) concatenated, and the rows each group gave.

    One read for a whole folder (a step's chunks are a group): per-step reads and
    concatenations copied an overnight folder's 10 M samples twice more. Of the
    optional columns only ``optional`` are read (those every chunk has); all rows.
    """
    records = [Path(run_dir) / rel for group in groups for rel in group]
    if not records:
        return {name: np.empty(0) for name in SAMPLE_COLUMNS}, [0] * len(groups)
    tables = _read_all(records, [*SAMPLE_COLUMNS, *optional])
    missing = [n for n in SAMPLE_COLUMNS if not all(n in t.column_names for t in tables)]
    if missing:
        where = next(p for p, t in zip(records, tables, strict=True) if missing[0] not in t.column_names)
        raise ChunkReadError(f"{where}: sample chunk lacks column {missing[0]!r}")
    sizes = iter(t.num_rows for t in tables)
    rows = [sum(next(sizes) for _ in group) for group in groups]
    return _joined(tables), rows


def read_chunks(run_dir: Path, records: Sequence[str]) -> dict[str, np.ndarray]:
    """The named chunks (relative paths) concatenated column by column, all rows."""
    return read_chunk_groups(run_dir, [records])[0]


def chunk_columns(path: Path, columns: Sequence[str]) -> dict[str, np.ndarray]:
    """Columns of one chunk, all rows, float64 (the live page's look at the running attempt).

    FileNotFoundError passes (a chunk being replaced right now); a missing column or an
    unreadable file is a :class:`ChunkReadError` naming it.
    """
    table = _read(Path(path), columns)
    absent = [c for c in columns if c not in table.column_names]
    if absent:
        raise ChunkReadError(f"{path}: cannot be read as a sample chunk (no column "
                             f"{absent[0]!r}); the run folder is damaged")
    return {c: np.asarray(column_array(table.column(c)), dtype=float) for c in columns}


def chunk_ranges(path: Path) -> dict[str, tuple[float, float]]:
    """Each column's (min, max) from the chunk's footer statistics, not its data.

    A night of chunks costs a few kilobytes per look (the live page's conditions plot).
    Columns without statistics are left out.
    """
    meta = _open(Path(path)).metadata
    try:
        names = [meta.schema.column(i).name for i in range(meta.num_columns)]
        lo: dict[str, float] = {}
        hi: dict[str, float] = {}
        for g in range(meta.num_row_groups):
            group = meta.row_group(g)
            for i, name in enumerate(names):
                stats = group.column(i).statistics
                if stats is None or not stats.has_min_max:
                    continue
                lo[name] = min(lo.get(name, np.inf), float(stats.min))
                hi[name] = max(hi.get(name, -np.inf), float(stats.max))
    except (OSError, pa.ArrowException, TypeError, ValueError) as exc:
        raise _damaged(Path(path), exc) from None
    return {name: (lo[name], hi[name]) for name in lo}
