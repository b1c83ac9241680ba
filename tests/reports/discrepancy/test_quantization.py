"""Pulse-counting quantization is named from the output lattice, never as a spurious line.

Truth comes from the project's simulator with the catalogue's quantization
effect (output = sf·(⌊Θ_k/q⌋ − ⌊Θ_{k−1}/q⌋)·q·fs, gyro-model.md); before this
module a 1″ pulse at 200 Hz was reported as periodic_interference at a
spurious 13.8 Hz and a 0.5″ pulse crashed the noise fit (OverflowError).
"""

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.quantization import detect_pulse, line_within_quantization
from gyrocal.models.gyro_model import EffectSpec

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
