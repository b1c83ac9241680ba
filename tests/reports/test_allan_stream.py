"""Streaming exact ADEV: bounded buffers, equal to the in-memory result, allantools and NBS14.

The long-τ path (three separate reads per block) only runs when m exceeds the
block; the tests shrink the block to a few tiles so a short record exercises
it, and spill the phase to a real temporary file.
"""

from __future__ import annotations

import allantools
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gyrocal.analysis.allan.deviation import adev_from_blocks, log_spaced_m, overlapping_adev
from gyrocal.analysis.allan.kernel import TILE
from gyrocal.analysis.allan.sources import open_record
from gyrocal.analysis.allan.stream import FilePhase, MemoryPhase, rechunk, record_stats, write_phase
from gyrocal.analysis.measured_log import LogFormatError

pytestmark = pytest.mark.timeout(120)


def _chunks(y: np.ndarray, size: int):
    return lambda: (y[i : i + size] for i in range(0, y.size, size))


def _nbs14_1000() -> np.ndarray:
    """NIST SP 1065 §12.4: n0 = 1234567890, n_{i+1} = 16807·n_i mod 2^31−1, y_i = n_i/(2^31−1)."""
    values = [1234567890]
    for _ in range(999):
        values.append(16807 * values[-1] % 2147483647)
    return np.array(values, dtype=float) / 2147483647.0


def test_nbs14_published_values_on_the_streaming_path(tmp_path):
    y = _nbs14_1000()
    result = adev_from_blocks(_chunks(y, 77), 1.0, m=[1, 10, 100], tmp_dir=tmp_path,
                              block=TILE, confidence=None)
    assert [float(f"{v:.6e}") for v in result.adev] == [2.922319e-1, 9.159953e-2, 3.241343e-2]


@pytest.mark.parametrize("kind", ["white", "random_walk"])
def test_streamed_equals_allantools_at_every_tau(tmp_path, kind):
    rng = np.random.default_rng(21)
    y = rng.standard_normal(60_000) + 4.0
    if kind == "random_walk":
        y = np.cumsum(y - 4.0) * 0.01
    m = log_spaced_m(y.size)
    streamed = adev_from_blocks(_chunks(y, 9_999), 50.0, m=m, confidence=None,
                                tmp_dir=tmp_path, block=2 * TILE)
    taus, adev, _, ns = allantools.oadev(y, rate=50.0, data_type="freq", taus=m / 50.0)
    np.testing.assert_array_equal(streamed.n_terms, ns)
    np.testing.assert_allclose(streamed.adev, adev, rtol=1e-9, atol=0)
    assert m.max() > 2 * TILE  # the long-τ (three-read) path ran


def test_streamed_is_bit_identical_to_in_memory_across_block_sizes(tmp_path):
    rng = np.random.default_rng(8)
    y = 11.0 + rng.standard_normal(123_457) + np.cumsum(rng.standard_normal(123_457)) * 1e-3
    reference = overlapping_adev(y, 100.0)
    for block, window, chunk in [(TILE, TILE, 1000), (TILE, 5 * TILE, 4096),
                                 (3 * TILE, 8 * TILE, 65_536), (16 * TILE, 40 * TILE, 123_457)]:
        streamed = adev_from_blocks(_chunks(y, chunk), 100.0, tmp_dir=tmp_path, block=block,
                                    window=window)
        np.testing.assert_array_equal(streamed.adev, reference.adev)
        np.testing.assert_array_equal(streamed.alpha, reference.alpha)
    assert not list(tmp_path.iterdir())  # the phase file is removed afterwards


def test_phase_file_holds_the_same_phase_as_memory(tmp_path):
    y = np.random.default_rng(2).standard_normal(10_001)
    stats = record_stats(rechunk([y], 333))
    memory, spilled = MemoryPhase(y.size + 1), FilePhase(tmp_path)
    try:
        write_phase([y], stats, 10.0, memory)
        write_phase(_chunks(y, 777)(), stats, 10.0, spilled)
        np.testing.assert_array_equal(spilled.read(0, y.size + 1), memory.array)
        np.testing.assert_array_equal(spilled.read(5000, 17), memory.array[5000:5017])
        # the phase is the mean-free running sum scaled by τ0, like allantools' frequency2phase
        expected = np.concatenate([[0.0], np.cumsum(y - y.mean()) / 10.0])
        np.testing.assert_allclose(memory.array, expected, rtol=0, atol=1e-12)
    finally:
        spilled.close()


def test_non_finite_sample_is_named_by_index():
    y = np.ones(1000)
    y[700] = np.nan
    with pytest.raises(ValueError, match="sample 700"):
        adev_from_blocks(_chunks(y, 64), 1.0)


def _write_parquet(path, t, rate, rate_name="gyro"):
    pq.write_table(pa.table({"t_s": t, rate_name: rate}), path)
    return path


def test_multi_file_parquet_log_equals_the_whole_record(tmp_path):
    fs = 200.0
    y = np.random.default_rng(5).standard_normal(90_000)
    t = np.arange(y.size) / fs
    paths = [_write_parquet(tmp_path / f"hour{i}.parquet", t[i * 30_000 : (i + 1) * 30_000],
                            y[i * 30_000 : (i + 1) * 30_000]) for i in range(3)]
    record = open_record(paths)
    assert record.n_samples == y.size and record.rate_hz == pytest.approx(fs)
    streamed = adev_from_blocks(record.blocks, record.rate_hz, tmp_dir=tmp_path)
    np.testing.assert_array_equal(streamed.adev, overlapping_adev(y, fs).adev)


def test_files_out_of_order_are_a_gap_named_by_file_and_line(tmp_path):
    fs = 100.0
    t = np.arange(3000) / fs
    y = np.zeros(3000)
    first = _write_parquet(tmp_path / "a.parquet", t[:1500], y[:1500])
    second = _write_parquet(tmp_path / "b.parquet", t[1500:], y[1500:])
    record = open_record([second, first])
    with pytest.raises(LogFormatError, match=r"a\.parquet: line 2 \(data row 1\): column t_s"):
        adev_from_blocks(record.blocks, record.rate_hz)


def test_plain_two_column_csv_without_header_and_with_common_names(tmp_path):
    fs = 50.0
    y = np.random.default_rng(9).standard_normal(5000)
    t = np.arange(y.size) / fs
    bare = tmp_path / "bare.csv"
    np.savetxt(bare, np.column_stack([t, y]), delimiter=",", fmt="%.17g")
    named = tmp_path / "named.csv"
    np.savetxt(named, np.column_stack([t, y]), delimiter=",", fmt="%.17g",
               header="time,rate_dps", comments="")
    expected = overlapping_adev(y, fs, confidence=None).adev
    for path in (bare, named):
        record = open_record([path])
        assert record.rate_hz == pytest.approx(fs)
        result = adev_from_blocks(record.blocks, record.rate_hz, confidence=None)
        np.testing.assert_allclose(result.adev, expected, rtol=1e-12)


def test_ambiguous_rate_columns_ask_for_column(tmp_path):
    path = tmp_path / "imu.csv"
    table = np.zeros((100, 4))
    table[:, 0] = np.arange(100) / 10.0
    np.savetxt(path, table, delimiter=",", header="t_s,gyro_x,gyro_y,gyro_z", comments="")
    with pytest.raises(LogFormatError, match="ambiguous.*gyro_x, gyro_y, gyro_z.*--column"):
        open_record([path])
    assert open_record([path], column="gyro_y").column == "gyro_y"
