"""The `quantization` effect reproduces Golyaev & Kolbas (1991, seeds/001).

Claims of the paper checked here: the count per readout is 0 or 1 pulse off
the true advance (floor or ceiling), the error does not accumulate, its
variance for a steady rate is f(1−f) with f the fractional phase advance per
readout (so it depends only on f, not on the whole pulses), and averaged over
uniformly spread rates its RMS is √(1/6) ≈ 0.408 pulse (measured 0.36–0.47).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrocal.models.gyro_model import EffectSpec, GyroModel
from gyrocal.models.gyro_sim import GyroSimulator
from gyrocal.models.pulse_counting import count_pulses

pytestmark = pytest.mark.timeout(60)

PULSE_ARCSEC = 2.0
Q_DEG = PULSE_ARCSEC / 3600.0
FS = 200.0


def rlg(**kw) -> GyroModel:
    return GyroModel(version=1, scale_factor=1.0, **kw).with_effect(
        EffectSpec("quantization", {"pulse_arcsec": PULSE_ARCSEC})
    )


def readout_errors(advance_pulses: float, n: int, phase: float = 0.0) -> np.ndarray:
    counts, _ = count_pulses(np.full(n, advance_pulses), phase)
    return counts - advance_pulses


def test_each_readout_counts_the_floor_or_the_ceiling_of_the_true_advance():
    rng = np.random.default_rng(1)
    n = 50_000
    t = np.arange(n) / FS
    rate = 3.0 * np.sin(t / 9.0) + rng.normal(0.0, 0.2, n)  # deg/s, sign changes included
    out = GyroSimulator(rlg(), FS, seed=0).generate(rate, 20.0)
    counts = out.gyro / FS / Q_DEG
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    counts = np.round(counts)
    advance = out.rate_ideal_dps / FS / Q_DEG  # noise-free model: ideal = true rate
    np.testing.assert_allclose(out.rate_ideal_dps, rate, rtol=1e-15)
    assert np.all((counts == np.floor(advance)) | (counts == np.ceil(advance)))
    error = counts - advance
    assert np.all(np.abs(error) < 1.0)


def test_the_error_does_not_accumulate_over_a_long_run():
    rng = np.random.default_rng(2)
    model = rlg(bias_dph=0.01, earth_rate_dph=11.6)
    sim = GyroSimulator(model, FS, seed=0)
    counted, true = [], []
    for _ in range(10):  # 10 blocks of 100 000 readouts = 5000 s
        rate = rng.uniform(-50, 50) + rng.normal(0, 0.5, 100_000)
        out = sim.generate(rate, 25.0)
        counted.append(out.gyro / FS / Q_DEG)
        true.append(out.rate_ideal_dps / FS / Q_DEG)
    # long double sums: 1e6 readouts of up to 450 pulses reach 1e8 pulses, where
    # float64 summation alone would drift by ~1e-6 pulse
    angle_error = np.cumsum(np.concatenate(counted), dtype=np.longdouble) - np.cumsum(
        np.concatenate(true), dtype=np.longdouble)
    # Σcounts = ⌊Θ/q⌋: the counted angle trails the true one by less than one pulse
    assert angle_error.max() < 1e-5
    assert angle_error.min() > -1.0 - 1e-5
    # while the per-readout errors themselves are of order one pulse
    per_readout = np.concatenate(counted) - np.concatenate(true)
    assert np.std(per_readout) > 0.2


@pytest.mark.parametrize("f", [0.1, 0.25, 0.5, 0.7, 1 / 3])
def test_variance_for_a_steady_rate_is_f_times_one_minus_f(f):
    errors = readout_errors(f, 12_000)  # a whole number of cycles for these rational f
    # the error is −f (no pulse) or 1−f (one pulse), mean 0
    assert np.all(np.isclose(errors, -f) | np.isclose(errors, 1.0 - f))
    assert np.mean(errors) == pytest.approx(0.0, abs=1e-3)
    assert np.var(errors) == pytest.approx(f * (1.0 - f), rel=2e-3)


@pytest.mark.parametrize("whole_pulses", [0, 1, 3, 57, -4])
def test_variance_depends_only_on_the_fractional_advance(whole_pulses):
    f = math.sqrt(2.0) - 1.0  # 0.414…, irrational: the phase sequence is equidistributed
    errors = readout_errors(whole_pulses + f, 20_000, phase=0.3)
    assert np.var(errors) == pytest.approx(f * (1.0 - f), rel=0.01)


def test_rms_over_uniformly_spread_rates_is_0_41_pulse():
    rng = np.random.default_rng(3)
    advances = rng.uniform(0.0, 40.0, 400)  # rates spread over many pulses per readout
    sq = [np.mean(readout_errors(a, 2000, phase=rng.uniform()) ** 2) for a in advances]
    rms = math.sqrt(np.mean(sq))
    assert rms == pytest.approx(math.sqrt(1.0 / 6.0), abs=0.012)  # 0.408
    assert 0.36 <= rms <= 0.47  # the paper's measured range


def test_simulator_quantization_error_field_is_the_count_error():
    rate = np.full(4000, 0.3 * Q_DEG * FS)  # 0.3 pulse per readout
    out = GyroSimulator(rlg(), FS, seed=0).generate(rate, 25.0)
    error_pulses = out.quantization_dps / FS / Q_DEG
    assert np.var(error_pulses) == pytest.approx(0.3 * 0.7, rel=5e-3)
    assert abs(np.sum(error_pulses)) < 1.0
