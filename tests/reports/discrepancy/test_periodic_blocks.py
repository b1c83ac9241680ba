"""periodic.py's frequency refinement demodulates the record a few thousand blocks at a time.

The oracle is the whole-record computation it replaced (one complex array of
the record's length, 160 MB per temporary on an overnight log): the block sums
must be the same numbers to the last bit, whatever the record length, including
lengths just above the block count, where two blocks can share a start.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.periodic import _REFINE_BLOCKS, _demodulated_blocks, periodic_scan


def _whole_record(r: np.ndarray, t: np.ndarray, f0: float, blocks: int) -> tuple[np.ndarray, np.ndarray]:
    n = r.size
    tt = t - t[0]
    z = r * np.exp(-2j * math.pi * f0 * tt)
    starts = np.linspace(0, n, blocks + 1).astype(np.int64)[:-1]
    return (np.add.reduceat(z, starts),
            np.add.reduceat(tt, starts) / np.diff(np.append(starts, n)))


@pytest.mark.parametrize("n", [5_000, _REFINE_BLOCKS, _REFINE_BLOCKS + 1, 65_539, 131_071, 1_000_003])
def test_block_sums_equal_the_whole_record_ones(n):
    rng = np.random.default_rng(n)
    fs_hz = 250.0
    t = 3.7 + np.arange(n) / fs_hz
    r = rng.standard_normal(n) + 0.3 * np.sin(2 * math.pi * 17.3 * t)
    blocks = min(_REFINE_BLOCKS, n)
    z, tb = _demodulated_blocks(r, t, 17.29, blocks)
    z0, tb0 = _whole_record(r, t, 17.29, blocks)
    assert z.shape == z0.shape == (blocks,)
    np.testing.assert_array_equal(z, z0)
    np.testing.assert_array_equal(tb, tb0)


def test_scan_finds_the_line_and_keeps_no_view_of_the_spectrum():
    n, fs_hz = 400_000, 250.0
    rng = np.random.default_rng(7)
    t = np.arange(n) / fs_hz
    resid = rng.standard_normal(n) * 2.0 + 0.5 * np.sin(2 * math.pi * 41.7 * t)
    scan = periodic_scan(resid, fs_hz, NoiseModel(arw_deg_per_rth=2.0 / 60.0 / math.sqrt(fs_hz / 3600.0)),
                         0.25, t)
    assert scan is not None
    assert abs(scan.freq_hz - 41.7) < fs_hz / n
    assert abs(scan.amplitude_dph - 0.5) < 0.05
    # the plotted frequencies are their own small array, not a view pinning the whole spectrum's
    assert scan.f_hz.base is None and scan.f_hz.size == scan.ratio.size < 8000
