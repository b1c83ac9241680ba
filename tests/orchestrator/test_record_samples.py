"""The run record's one reader of sample chunks and its one rule for which attempt counts (issue 27).

A real run folder written by the product's writer (RunFolder, Journal): a step
logged twice (attempt 1 bad, attempt 2 completed with two samples the gyro
flagged), a ramp completed without samples, and a chunk of an attempt that
never completed. The engine's resume, the reports' reader, the streamed Allan
blocks and the discrepancy workflow's measured log must all see the same
thing: the counted attempt, good samples only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gyrocal.analysis.measured_log import read_run_folder_log
from gyrocal.errors import BadInput
from gyrocal.record.journal import JournalEvent
from gyrocal.record.logged_steps import attempts_started, completed_attempts, counted_attempts
from gyrocal.record.run_folder import _DICTIONARY_COLUMNS, RunFolder
from gyrocal.record.samples import ChunkReadError, RunSamples, column_array, samples

REPO = Path(__file__).resolve().parents[2]
N = 50


def _columns(gyro: np.ndarray, t0_s: float, status: np.ndarray) -> dict[str, np.ndarray]:
    n = gyro.size
    return {"t_s": t0_s + np.arange(n) / 100.0, "table_rate_dps": np.zeros(n),
            "chamber_temp_c": np.full(n, 25.0), "gyro": gyro, "sensor_temp_c": np.full(n, 30.0),
            "table_angle_deg": np.zeros(n), "status": status.astype(np.uint8)}


@pytest.fixture
def run(tmp_path: Path) -> Path:
    folder = RunFolder.create(tmp_path / "run", REPO / "procedures" / "smoke.yaml", None,
                              manifest_fields={"mode": "sim"})
    journal = folder.open_journal()
    journal.append(JournalEvent.STEP_STARTED, step_id="T01.ramp", attempt=1)
    journal.append(JournalEvent.STEP_COMPLETED, step_id="T01.ramp", attempt=1)
    # attempt 1 of the hold: logged, then judged bad (its chunk stays, never counted)
    journal.append(JournalEvent.STEP_STARTED, step_id="T01.static", attempt=1)
    bad = folder.write_chunk("T01.static", 1, 0, _columns(np.full(N, 99.0), 0.0, np.zeros(N)))
    journal.append(JournalEvent.CHUNK_WRITTEN, step_id="T01.static", attempt=1, path=bad.path,
                   sha256=bad.sha256, rows=bad.rows)
    journal.append(JournalEvent.STEP_BAD, step_id="T01.static", attempt=1, reason="frame loss")
    # attempt 2: two chunks, samples 3 and 60 flagged by the gyro
    status = np.zeros(2 * N)
    status[[3, 60]] = 1
    good = np.arange(2 * N, dtype=float)
    journal.append(JournalEvent.STEP_STARTED, step_id="T01.static", attempt=2)
    chunks = []
    for index in range(2):
        part = slice(index * N, (index + 1) * N)
        record = folder.write_chunk("T01.static", 2, index,
                                    _columns(good[part], index * N / 100.0, status[part]))
        journal.append(JournalEvent.CHUNK_WRITTEN, step_id="T01.static", attempt=2,
                       path=record.path, sha256=record.sha256, rows=record.rows)
        chunks.append(record.path)
    journal.append(JournalEvent.STEP_COMPLETED, step_id="T01.static", attempt=2, chunks=chunks,
                   samples=2 * N)
    # a later step started and cut off: its chunk is on disk, its attempt never completed
    journal.append(JournalEvent.STEP_STARTED, step_id="T01.sf.+10dps", attempt=1)
    cut = folder.write_chunk("T01.sf.+10dps", 1, 0, _columns(np.full(N, 10.0), 5.0, np.zeros(N)))
    journal.append(JournalEvent.CHUNK_WRITTEN, step_id="T01.sf.+10dps", attempt=1, path=cut.path,
                   sha256=cut.sha256, rows=cut.rows)
    folder.close()
    return folder.path


def test_the_engine_and_the_readers_count_the_same_attempts(run: Path) -> None:
    events = RunFolder.open(run).journal_events()
    assert list(counted_attempts(events)) == ["T01.ramp", "T01.static"]     # resume skips these
    assert attempts_started(events) == {"T01.ramp": 1, "T01.static": 2, "T01.sf.+10dps": 1}
    assert list(completed_attempts(events)) == ["T01.static"]             # those with samples
    assert list(RunSamples(run).logged) == ["T01.static"]


def test_a_step_reads_its_counted_attempt_good_samples_only(run: Path) -> None:
    expected = np.delete(np.arange(2 * N, dtype=float), [3, 60])
    step = samples(run, "T01.static", columns=("gyro", "t_s"))
    assert step.attempt == 2 and step.n_logged == 2 * N and step.n == 2 * N - 2
    np.testing.assert_array_equal(step["gyro"], expected)      # not attempt 1's 99s
    assert set(step.columns) == {"gyro", "t_s"}                # status read, not handed out
    every = RunSamples(run).step("T01.static", ("gyro",), good_only=False)
    np.testing.assert_array_equal(every["gyro"], np.arange(2 * N, dtype=float))
    streamed = np.concatenate(list(RunSamples(run).blocks("T01.static", "gyro")))
    np.testing.assert_array_equal(streamed, expected)
    assert RunSamples(run).count("T01.static") == 2 * N - 2
    assert RunSamples(run).count("T01.static", good_only=False) == 2 * N


def test_the_measured_log_of_a_run_folder_is_the_same_samples(run: Path) -> None:
    log = read_run_folder_log(run)
    np.testing.assert_array_equal(log.gyro, np.delete(np.arange(2 * N, dtype=float), [3, 60]))
    assert set(log.segment) == {"T01.static"}


def test_a_damaged_chunk_is_bad_input_naming_the_file(run: Path) -> None:
    chunk = sorted((run / "samples" / "T01.static").glob("attempt2-*.parquet"))[0]
    chunk.write_bytes(b"not parquet at all")
    with pytest.raises(ChunkReadError) as caught:
        samples(run, "T01.static")
    assert str(chunk) in str(caught.value) and isinstance(caught.value, BadInput)


@pytest.mark.parametrize("column", [
    pa.chunked_array([pa.array([1.0, np.nan, 3.0]), pa.array([], pa.float64()),
                      pa.array([4.0, 5.0, 6.0]).slice(1)]),          # NaN, an empty chunk, an offset
    pa.chunked_array([pa.array([7, 8, 9], pa.uint8()).slice(2), pa.array([255], pa.uint8())]),
    pa.chunked_array([], pa.float64()),
    pa.chunked_array([pa.array([1, None, 3])]),                      # nulls: left to to_numpy
    pa.chunked_array([pa.array([True, False])]),                     # bit-packed: likewise
])
def test_a_column_reads_as_to_numpy_gives_it(column: pa.ChunkedArray) -> None:
    """The reader copies number columns from their buffers (no pandas import): the same
    dtype and values as pyarrow's ``to_numpy``, and a writable array of its own."""
    got, expected = column_array(column), column.to_numpy()
    assert got.dtype == expected.dtype
    np.testing.assert_array_equal(got, expected)
    got[...] = 0            # a copy: writing it leaves the Arrow buffers alone
    np.testing.assert_array_equal(column.to_numpy(), expected)


def test_a_chunk_is_the_parquet_that_pa_array_columns_make(tmp_path: Path) -> None:
    """RunFolder.write_chunk wraps the NumPy buffers (no pandas import); the file is the
    one ``pa.array`` columns make, byte for byte (NaN a value, not a null)."""
    folder = RunFolder.create(tmp_path / "run", REPO / "procedures" / "smoke.yaml", None,
                              manifest_fields={"mode": "sim"})
    columns = _columns(np.array([0.5, np.nan, -np.inf, 2.0]), 10.0, np.array([0, 1, 0, 0]))
    columns["gyro"] = columns["gyro"][::1]
    columns["sensor_temp_c"] = np.arange(8.0)[::2]                  # not contiguous
    record = folder.write_chunk("T01", 1, 0, columns)
    table = pa.table({name: pa.array(np.asarray(values, dtype=np.uint8 if name == "status"
                                                else np.float64))
                      for name, values in columns.items()})
    expected = pa.BufferOutputStream()
    pq.write_table(table.select([n for n in pq.read_schema(folder.path / record.path).names]),
                   expected, compression="zstd", use_dictionary=_DICTIONARY_COLUMNS)
    assert (folder.path / record.path).read_bytes() == expected.getvalue().to_pybytes()
