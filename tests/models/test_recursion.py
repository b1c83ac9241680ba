"""The compiled first-order recursion gives scipy's lfilter bits (dry runs keep their samples)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from gyrocal.models import recursion
from gyrocal.models.noise import FlickerNoise, GaussMarkov
from gyrocal.models.recursion import first_order, first_order_sum
from gyrocal.models.temperature import thermal_lag_c


def _lfilter(gain: float, a: float, x: np.ndarray, y_prev: float) -> np.ndarray:
    return lfilter([gain], [1.0, -a], x, zi=[a * y_prev])[0]


def test_compiled_kernel_is_in_use():
    assert recursion.AVAILABLE, "numba is a declared dependency: the compiled loop must be used"


@pytest.mark.parametrize("seed", range(8))
def test_same_bits_as_lfilter_over_the_noise_bank_range(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        n = int(rng.integers(1, 3000))
        fs_hz = float(rng.choice([0.0038, 3.9, 125.0, 250.0, 2000.0]))   # decimated knot grids too
        tau_s = float(10 ** rng.uniform(-1, 6))                           # the flicker bank's band
        a = float(np.exp(-1.0 / (fs_hz * tau_s)))
        gain = float(rng.uniform(0.0, 3.0) * np.sqrt(-np.expm1(-2.0 / (fs_hz * tau_s))))
        x = rng.standard_normal(n) * float(rng.choice([1e-3, 1.0, 1e4]))
        y_prev = float(rng.standard_normal() * 10.0)
        assert first_order(gain, a, x, y_prev).tobytes() == _lfilter(gain, a, x, y_prev).tobytes()


def test_unit_gain_as_the_thermal_lag_uses_it():
    u = np.linspace(-10.0, 40.0, 5000) + np.sin(np.arange(5000) / 50.0)
    a = float(np.exp(-0.004 / 300.0))
    assert first_order(1.0, a, u, 21.5).tobytes() == _lfilter(1.0, a, u, 21.5).tobytes()


def test_gauss_markov_blocks_equal_lfilter_reference():
    """The process itself: its blocks are the lfilter recursion over its own draws."""
    process = GaussMarkov(2.0, 30.0, 250.0, seed=np.random.SeedSequence(11))
    twin = np.random.default_rng(np.random.SeedSequence(11))
    x = 2.0 * twin.standard_normal()
    for n in (1, 7, 2500, 8192):
        got = process.generate(n)
        want = _lfilter(process._gain, process._a, twin.standard_normal(n), x)
        x = float(want[-1])
        assert got.tobytes() == want.tobytes()


def test_thermal_lag_uniform_grid_is_the_recursion():
    tc = np.concatenate((np.full(100, 25.0), np.linspace(25.0, -10.0, 4000)))
    tau_s, dt_s = 120.0, 0.004
    got = thermal_lag_c(tc, dt_s, tau_s, sensor_prev_c=25.5, chamber_prev_c=25.0)
    one_minus_a = -np.expm1(-np.array([dt_s]) / tau_s)
    a = 1.0 - one_minus_a
    b0 = 1.0 - tau_s * one_minus_a / dt_s
    u = b0 * tc + (one_minus_a - b0) * np.concatenate(([25.0], tc[:-1]))
    assert got.tobytes() == _lfilter(1.0, float(a[0]), u, 25.5).tobytes()


def test_a_bank_summed_in_one_call_equals_the_sum_of_its_filters():
    """The flicker noise's processes side by side: the sum from 0 in row order, bit for bit,
    and each process's last value carried out."""
    rng = np.random.default_rng(3)
    for n in (1, 2, 37, 2300):
        rows = int(rng.integers(1, 9))
        gains = rng.uniform(0.01, 2.0, rows)
        poles = np.exp(-1.0 / (250.0 * 10 ** rng.uniform(-1, 6, rows)))
        lasts = rng.standard_normal(rows)
        drives = rng.standard_normal((rows, n))
        filtered = [_lfilter(g, a, d, y) for g, a, d, y in zip(gains, poles, drives, lasts, strict=True)]
        want = sum(filtered)
        carried = lasts.copy()
        assert first_order_sum(gains, poles, carried, drives).tobytes() == want.tobytes()
        assert carried.tolist() == [float(f[-1]) for f in filtered]


def test_the_flicker_bank_draws_and_sums_as_its_processes_one_by_one():
    """FlickerNoise through the one-call bank gives what its processes give one by one."""
    noise = FlickerNoise(0.05, 250.0, seed=np.random.SeedSequence(4))
    twin = FlickerNoise(0.05, 250.0, seed=np.random.SeedSequence(4))
    for n in (1, 100, 2500, 70000):
        got = noise.generate(n)
        want = np.zeros(n)
        for group in twin.groups:      # the knot arithmetic as written, each process alone
            want += _one_by_one(group, n)
        assert got.tobytes() == want.tobytes()


def _one_by_one(group, n):
    d = group.decimation
    sample = group._index + np.arange(n)
    needed = (group._index + n - 1) // d + 1
    have = group._first_knot + len(group._knots) - 1
    if needed > have:
        group._knots = np.concatenate((group._knots, sum(p.generate(needed - have)
                                                         for p in group.processes)))
    knot_sample = (group._first_knot + np.arange(len(group._knots))) * float(d)
    out = np.interp(sample.astype(float), knot_sample, group._knots)
    group._index += n
    keep_from = group._index // d - group._first_knot
    group._knots = group._knots[keep_from:]
    group._first_knot += keep_from
    return out
