"""Frequency response: the simulator's rate_bandwidth (models/effects.py) measured back.

Hand-typed truth: a first-order response with f_c = 50 Hz has gain 1/√(1+(f/50)²) and
phase −atan(f/50); its −3 dB bandwidth is 50 Hz and its phase at 50 Hz −45°.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrocal.analysis.rate.frequency_response import (
    ResponsePoint,
    bandwidth_3db,
    fit_sine,
    phase_at,
    response_point,
)
from gyrocal.models.gyro_model import EffectSpec, GyroModel, NoiseParams
from gyrocal.models.gyro_sim import simulate

pytestmark = pytest.mark.timeout(60)
FS_HZ = 2000.0
FC_HZ = 50.0
FREQS_HZ = (5.0, 10.0, 20.0, 30.0, 40.0, 60.0, 80.0, 120.0)


def model(bandwidth_hz: float | None) -> GyroModel:
    gyro = GyroModel(version=1, scale_factor=1.0, reference_temp_c=25.0, bias_dph=2.0,
                     noise=NoiseParams(arw_deg_per_rth=0.01))
    if bandwidth_hz is not None:
        gyro = gyro.with_effect(EffectSpec("rate_bandwidth", {"bandwidth_hz": bandwidth_hz}))
    return gyro


def sweep(gyro: GyroModel, seed: int, amplitude_dps: float = 1.0) -> list[ResponsePoint]:
    points = []
    for index, freq in enumerate(FREQS_HZ):
        t = np.arange(int(2.0 * FS_HZ)) / FS_HZ
        rate = amplitude_dps * np.sin(2 * math.pi * freq * t + 0.3)
        out = simulate(gyro, t, rate, 25.0, seed=seed + index).gyro
        points.append(response_point(t, out, rate, freq, 1.0))
    return points


def test_a_sine_fit_reads_amplitude_and_phase_typed_here():
    t = np.arange(4000) / FS_HZ
    sine = fit_sine(t, 2.0 * np.sin(2 * math.pi * 7.0 * t - 0.5) + 0.1, 7.0)
    assert sine.amplitude == pytest.approx(2.0, abs=1e-12)
    assert sine.phase_rad == pytest.approx(-0.5, abs=1e-12)


def test_the_first_order_bandwidth_is_measured_back_within_its_uncertainty():
    points = sweep(model(FC_HZ), seed=11)
    for p in points:
        truth_gain = 1 / math.sqrt(1 + (p.freq_hz / FC_HZ) ** 2)
        truth_phase = -math.degrees(math.atan(p.freq_hz / FC_HZ))
        # the simulator holds the sampled rate linear between samples: a sine loses about
        # (2πf/fs)²/12 of its amplitude to that (0.5 % at 80 Hz, 2000 Hz sampling)
        holding = (2 * math.pi * p.freq_hz / FS_HZ) ** 2 / 12
        assert abs(p.gain / truth_gain - 1) < holding + 2e-3, p
        assert abs(p.phase_deg - truth_phase) < 0.5, p
    bandwidth = bandwidth_3db(points)
    assert bandwidth is not None
    assert abs(bandwidth.value_hz - FC_HZ) <= bandwidth.expanded_hz
    assert bandwidth.expanded_hz < 3.0      # 40 → 60 Hz bracket, not the whole 20 Hz
    phase, u_phase = phase_at(points, FC_HZ)
    # linear between −38.7° (40 Hz) and −50.2° (60 Hz): −44.5°, within 1° of −45°
    assert phase == pytest.approx(-45.0, abs=1.0) and u_phase < 0.1


def test_without_the_bandwidth_entry_the_response_is_flat_and_has_no_crossing():
    points = sweep(model(None), seed=5)
    assert all(abs(p.gain - 1.0) < 1e-3 and abs(p.phase_deg) < 0.1 for p in points)
    assert bandwidth_3db(points) is None


def test_coverage_of_the_bandwidth_interval_over_seeds():
    """20 seeded sweeps: the truth lies inside value ± U every time (the type B
    interpolation term dominates U here; the noise alone would give far less)."""
    covered = 0
    for seed in range(20):
        bandwidth = bandwidth_3db(sweep(model(FC_HZ), seed=100 * seed, amplitude_dps=0.2))
        covered += abs(bandwidth.value_hz - FC_HZ) <= bandwidth.expanded_hz
    assert covered == 20
