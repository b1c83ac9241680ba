"""Block-by-block generation equals one long call (deterministic part and, per seed, noise)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gyrocal.models.gyro_model import EffectSpec, NoiseParams, load_model
from gyrocal.models.gyro_sim import GyroSimulator, simulate
from gyrocal.models.pulse_counting import PulseCounter

pytestmark = pytest.mark.timeout(60)

MODELS = Path(__file__).resolve().parents[2] / "gyro-models"
FS = 100.0


def busy_model():
    """The spec example plus every history-carrying effect and every noise term."""
    model = load_model(MODELS / "nominal-fog.yaml")
    for name, params in [
        ("temp_rate_bias", {"dph_per_c_per_min": 0.5}),
        ("temp_hysteresis", {"dph": 0.2}),
        ("warmup_transient", {"amplitude_dph": 3.0, "tau_s": 30.0}),
        ("table_angle_harmonic", {"amplitude_dph": 0.5, "phase_deg": 10.0}),
        ("periodic_interference", {"freq_hz": 12.48, "amplitude_dph": 1.0}),
        ("dead_zone", {"threshold_dps": 0.01}),
        ("markov_bias", {"sigma_dph": 0.1, "tau_s": 20.0}),
    ]:
        model = model.with_effect(EffectSpec(name, params))
    noise = NoiseParams(0.5, 0.01, 0.03, 0.02, 0.5)
    return replace(model, noise=noise)


def profile(n: int):
    t = np.arange(n) / FS
    rate = np.where(t < 40, 0.0, 20.0 * np.sin(t / 7.0))
    chamber = 25.0 + 5.0 * np.sin(t / 25.0)
    return rate, chamber


def generate_in_blocks(model, sizes, seed, rate, chamber):
    sim = GyroSimulator(model, FS, seed=seed)
    blocks, i = [], 0
    for size in sizes:
        blocks.append(sim.generate(rate[i:i + size], chamber[i:i + size]))
        i += size
    assert sim.samples_emitted == i
    return {k: np.concatenate([getattr(b, k) for b in blocks]) for k in blocks[0].__dict__}


def test_blocks_equal_one_call_for_the_same_seed():
    model = busy_model()
    n = 12_000
    rate, chamber = profile(n)
    whole = GyroSimulator(model, FS, seed=42).generate(rate, chamber)
    parts = generate_in_blocks(model, [1, 7, 3000, 992, 5000, 3000], 42, rate, chamber)
    np.testing.assert_array_equal(parts["t_s"], whole.t_s)
    for key in ("rate_ideal_dps", "sensor_temp_c", "table_angle_deg", "noise_dph", "gyro"):
        np.testing.assert_allclose(parts[key], getattr(whole, key), rtol=1e-12, atol=1e-12,
                                   err_msg=key)
    assert np.std(whole.noise_dph) > 0  # the noise really is on


def test_different_seeds_differ_only_in_the_noise():
    model = busy_model()
    rate, chamber = profile(2000)
    a = GyroSimulator(model, FS, seed=1).generate(rate, chamber)
    b = GyroSimulator(model, FS, seed=2).generate(rate, chamber)
    np.testing.assert_array_equal(a.rate_ideal_dps, b.rate_ideal_dps)
    assert not np.allclose(a.noise_dph, b.noise_dph)


def test_simulate_matches_the_streaming_simulator():
    model = busy_model()
    n = 5000
    rate, chamber = profile(n)
    t = np.arange(n) / FS
    whole = simulate(model, t, rate, chamber, seed=9)
    sim = GyroSimulator(model, FS, seed=9)
    streamed = [sim.generate(rate[:2500], chamber[:2500]), sim.generate(rate[2500:], chamber[2500:])]
    for key in ("rate_ideal_dps", "noise_dph", "gyro"):
        np.testing.assert_allclose(np.concatenate([getattr(s, key) for s in streamed]),
                                   getattr(whole, key), rtol=1e-9, atol=1e-9, err_msg=key)


def test_quantized_output_streams_and_keeps_the_accumulator():
    model = load_model(MODELS / "rlg-dithered.yaml")
    n = 20_000
    rate, chamber = profile(n)
    whole = GyroSimulator(model, FS, seed=5).generate(rate, chamber)
    parts = generate_in_blocks(model, [333, 4000, 15667], 5, rate, chamber)
    q_deg = 2.0 / 3600.0
    counts_whole = whole.gyro / FS / q_deg
    counts_parts = parts["gyro"] / FS / q_deg
    np.testing.assert_allclose(counts_whole, np.round(counts_whole), atol=1e-6)  # whole pulses
    # same pulses (a float tie at a pulse edge could move one pulse by one readout: allow none here)
    np.testing.assert_array_equal(np.round(counts_parts), np.round(counts_whole))
    # decomposition: gyro = sf·(ideal + noise/3600 + quantization)
    np.testing.assert_allclose(
        whole.gyro, model.scale_factor * (whole.rate_ideal_dps + whole.noise_dph / 3600
                                          + whole.quantization_dps), atol=1e-12)


def test_scalar_inputs_with_n_and_time_continues():
    model = load_model(MODELS / "nominal-fog.yaml")
    sim = GyroSimulator(model, 200.0, seed=0, t0_s=100.0)
    first = sim.generate(0.0, 25.0, n=200)
    second = sim.generate(np.zeros(10), 25.0)
    assert first.t_s[0] == 100.0 and second.t_s[0] == pytest.approx(101.0)
    assert sim.t_next_s == pytest.approx(101.05)
    with pytest.raises(ValueError, match="differ in length"):
        sim.generate(np.zeros(3), np.zeros(4))
    assert len(sim.generate(np.zeros(0), np.zeros(0))) == 0  # an empty read is harmless
    assert sim.t_next_s == pytest.approx(101.05)


def test_pulse_counter_phase_is_validated():
    with pytest.raises(ValueError, match="must be > 0 arcsec"):
        PulseCounter(0.0)
    with pytest.raises(ValueError, match=r"in \[0, 1\)"):
        PulseCounter(1.0, phase_pulses=1.0)
