"""Pulse-counting quantization is named from the output lattice, never as a spurious line.

Truth comes from the project's simulator with the catalogue's quantization
effect (output = sf·(⌊Θ_k/q⌋ − ⌊Θ_{k−1}/q⌋)·q·fs, gyro-model.md); before this
module a 1″ pulse at 200 Hz was reported as periodic_interference at a
spurious 13.8 Hz and a 0.5″ pulse crashed the noise fit (OverflowError).
"""

from dataclasses import replace

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.own_gap import (
    SHORT_M,
    quantization_metrics,
    short_tau_avar_chunks,
)
from gyrocal.analysis.discrepancy.quantization import detect_pulse, line_within_quantization
from gyrocal.models.gyro_model import EffectSpec
from gyrocal.models.pulse_counting import PulseCounter

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def profile():
    return scenarios.procedure_profile(duration_s=1200.0, fs_hz=200.0, setpoints_c=(25.0, 30.0),
                                       ramps_c_per_min=(5.0,))


@pytest.mark.parametrize("pulse_arcsec", [0.5, 2.0])
def test_pulse_is_named_first_with_its_size_and_no_line(profile, pulse_arcsec):
    result = scenarios.analyse_scenario(
        profile, [EffectSpec("quantization", {"pulse_arcsec": pulse_arcsec})], seed=5, n_null=60)
    names = [f.name for f in result.found]
    assert names and names[0] == "quantization"
    assert "periodic_interference" not in names
    assert result.found[0].parameters["pulse_arcsec"] == pytest.approx(pulse_arcsec, rel=1e-6)


@pytest.mark.parametrize("pulse_arcsec", [0.5, 2.0])
def test_pulse_is_found_at_5_hz_with_slews(pulse_arcsec):
    """At 5 Hz a sample holds up to ~300,000 pulses and slews add a thousand levels: the pulse
    is still exact (before the staged least squares it came back 3e-4 off and unnamed)."""
    prof = scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)
    samples = scenarios.simulate_log(prof, [EffectSpec("quantization", {"pulse_arcsec": pulse_arcsec})],
                                     seed=9)
    lattice = detect_pulse(samples.gyro, scenarios.nominal_model().scale_factor, prof.fs_hz)
    assert lattice is not None
    assert lattice.pulse_arcsec == pytest.approx(pulse_arcsec, rel=1e-9)


def test_continuous_output_has_no_lattice(profile):
    samples = scenarios.simulate_log(profile, [], seed=3)
    model = scenarios.nominal_model()
    assert detect_pulse(samples.gyro, model.scale_factor, profile.fs_hz) is None
    # nor when written with 10 significant digits (a CSV log's own rounding is no lattice)
    rounded = np.array([float(f"{v:.10g}") for v in samples.gyro[:20000]])
    assert detect_pulse(rounded, model.scale_factor, profile.fs_hz) is None


def test_a_line_bounded_in_angle_by_the_pulse_is_its_beat():
    # 0.46 deg/h at 13.8 Hz moves the angle by 0.0053″: within a 1″ pulse
    assert line_within_quantization(0.46, 13.8, 1.0)
    # 12.48 Hz table interference of 500 deg/h moves it by 6.4″: not quantization
    assert not line_within_quantization(500.0, 12.48, 1.0)


def test_own_gap_closes_against_the_counter_not_white_angle_noise():
    """At 20 Hz a 1″ pulse is counted 0 or 1 per readout while the table is still: its residual's
    short-τ Allan curve is not q/√12 white angle noise, and only the counter run on the record's
    own rate history closes the gap (the white-angle reading left it at ~26× its floor in every
    20 and 50 Hz validation run)."""
    fs_hz, pulse_arcsec = 20.0, 1.0
    rng = np.random.default_rng(3)
    rate_dps = np.concatenate([np.zeros(6000), np.full(2000, 5.0), np.full(2000, -30.0), np.zeros(6000)])
    predicted_dph = rate_dps * 3600.0 + 2.0
    given = NoiseModel(arw_deg_per_rth=0.01)
    noisy_dps = (predicted_dph + rng.standard_normal(rate_dps.size) * given.white_sigma_dph(fs_hz)) / 3600.0
    resid_dph = PulseCounter(pulse_arcsec, 0.3).quantize(noisy_dps, 1.0 / fs_hz) * 3600.0 - predicted_dph
    gap = quantization_metrics(resid_dph, predicted_dph, fs_hz, given, pulse_arcsec, rng)
    metric = gap.metrics[gap.headline]
    assert metric.before >= 2.0 * metric.noise_floor
    assert metric.after <= 1.5 * metric.noise_floor
    # the white-angle-noise reading of the same residual stays far off: the model this replaced
    white_angle = replace(given, quantization_arcsec=pulse_arcsec / np.sqrt(12.0))
    # (the same statistic: RMS over the record's parts and τ of ln(ADEV / model ADEV)); against
    # the floor as the 90 % point of that statistic under noise alone, about 6× it here
    parts = short_tau_avar_chunks(resid_dph, fs_hz)
    model_avar = white_angle.allan_deviation_dph(SHORT_M / fs_hz) ** 2
    mismatch = np.sqrt(np.mean((0.5 * np.log(parts / model_avar)) ** 2))
    assert mismatch > 4.0 * metric.noise_floor
