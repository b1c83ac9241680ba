"""Each catalogue effect against its equation in gyro-model.md, with the noise off.

The expected values are written out here from the spec's equations (not from
the implementation), and compared exactly (to float rounding) wherever the
equation is exact on sampled inputs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyrocal.models.effects import EFFECTS
from gyrocal.models.gyro_model import EffectSpec, GyroModel
from gyrocal.models.gyro_sim import AliasingWarning, GyroSimulator, simulate
from gyrocal.models.indicated import ModelInputs, effect_contribution_dph, indicated_rate
from gyrocal.models.temperature import HYSTERESIS_BAND_C, hysteresis_sign, thermal_lag_c

pytestmark = pytest.mark.timeout(60)

FS = 10.0
SF = 2.5  # output units per deg/s, so the output scaling is checked too
T0 = 25.0


def base(**kw) -> GyroModel:
    return GyroModel(version=1, scale_factor=SF, reference_temp_c=T0, **kw)


def with_effects(model: GyroModel, *effects: tuple[str, dict]) -> GyroModel:
    for name, params in effects:
        model = model.with_effect(EffectSpec(name, params))
    return model


def run(model: GyroModel, rate_dps, temp_c, n: int, **kw):
    t = np.arange(n) / FS
    return t, simulate(model, t, rate_dps, temp_c, seed=0, **kw)


def bias_of(samples) -> np.ndarray:
    """Output bias in deg/h for a zero table rate."""
    return samples.gyro / SF * 3600.0


def test_catalogue_matches_the_contract():
    expected = {
        "thermal_lag": ["tau_s"],
        "temp_rate_bias": ["dph_per_c_per_min"],
        "temp_hysteresis": ["dph"],
        "bias_temp_quadratic": ["dph_per_c2"],
        "sf_temp_quadratic": ["ppm_per_c2"],
        "sf_nonlinearity_quadratic": ["k2_per_dps"],
        "sf_nonlinearity_cubic": ["k3_per_dps2"],
        "sf_asymmetry": ["ppm"],
        "dead_zone": ["threshold_dps"],
        "rate_bandwidth": ["bandwidth_hz"],
        "rate_saturation": ["positive_dps", "negative_dps"],
        "warmup_transient": ["amplitude_dph", "tau_s"],
        "bias_ramp": ["dph_per_h"],
        "table_angle_harmonic": ["amplitude_dph", "phase_deg"],
        "periodic_interference": ["freq_hz", "amplitude_dph"],
        "magnetic_sensitivity": ["dph_per_t"],
        "markov_bias": ["sigma_dph", "tau_s"],
        "quantization": ["pulse_arcsec"],
    }
    assert {k: list(v.keys) for k, v in EFFECTS.items()} == expected
    assert EFFECTS["warmup_transient"].linear_keys == ("amplitude_dph",)
    assert EFFECTS["table_angle_harmonic"].nonlinear_keys == ("phase_deg",)
    assert EFFECTS["periodic_interference"].nonlinear_keys == ("freq_hz",)
    assert EFFECTS["markov_bias"].stochastic and not EFFECTS["bias_ramp"].stochastic


def test_base_equation_bias_scale_factor_tempcos_and_earth_rate():
    model = base(bias_dph=2.0, bias_tempco_dph_per_c=0.03, sf_error_ppm=50.0,
                 sf_tempco_ppm_per_c=20.0, earth_rate_dph=15.041067 * math.sin(math.radians(48.0)))
    n = 200
    rate = np.linspace(-100, 100, n)
    temp = np.linspace(-10, 60, n)
    _, out = run(model, rate, temp, n)
    dt = temp - T0
    s_ppm = 50.0 + 20.0 * dt
    b_dph = 2.0 + 0.03 * dt + 15.041067 * math.sin(math.radians(48.0))
    np.testing.assert_allclose(out.gyro, SF * ((1 + 1e-6 * s_ppm) * rate + b_dph / 3600), rtol=1e-13)
    np.testing.assert_array_equal(out.sensor_temp_c, temp)  # no lag: T_s = T_c
    assert not np.any(out.noise_dph) and not np.any(out.quantization_dps)


def test_thermal_lag_follows_first_order_ode_and_drives_every_temperature_term():
    tau = 120.0
    ramp_c_per_s = 0.05
    model = with_effects(base(bias_tempco_dph_per_c=0.5), ("thermal_lag", {"tau_s": tau}))
    n = 20000  # 2000 s = 16.7 tau: settled to 6e-8
    t = np.arange(n) / FS
    chamber = 20.0 + ramp_c_per_s * t
    out = simulate(model, t, 0.0, chamber, seed=0)
    # exact solution of dT_s/dt = (T_c − T_s)/τ with T_s(0) = T_c(0) for a ramp
    sensor = 20.0 + ramp_c_per_s * (t - tau * (1.0 - np.exp(-t / tau)))
    np.testing.assert_allclose(out.sensor_temp_c, sensor, rtol=0, atol=1e-9)
    np.testing.assert_allclose(bias_of(out), 0.5 * (sensor - T0), rtol=0, atol=1e-8)
    # settled lag is r·τ
    assert chamber[-1] - out.sensor_temp_c[-1] == pytest.approx(ramp_c_per_s * tau, rel=1e-6)


def test_thermal_lag_handles_irregular_sampling_like_regular():
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.05, 0.15, 20000))
    chamber = 20.0 + 10.0 * np.sin(t / 300.0)
    dt = np.diff(t, prepend=t[0] - 0.1)
    irregular = thermal_lag_c(chamber, dt, 60.0)
    # reference: the same ODE integrated finely (chamber linear between samples)
    fine_t = np.linspace(t[0], t[-1], 400_001)
    fine = thermal_lag_c(np.interp(fine_t, t, chamber), fine_t[1] - fine_t[0], 60.0)
    np.testing.assert_allclose(irregular, np.interp(t, fine_t, fine), atol=1e-6)


def test_temp_rate_bias_uses_the_sensor_temperature_rate_in_c_per_min():
    k = 0.8  # deg/h per degC/min
    n = 3000
    t = np.arange(n) / FS
    chamber = 20.0 + 0.05 * t  # 3 degC/min
    no_lag = with_effects(base(), ("temp_rate_bias", {"dph_per_c_per_min": k}))
    out = simulate(no_lag, t, 0.0, chamber, seed=0)
    # causal backward difference: no history at the first sample, so 0 there
    assert bias_of(out)[0] == 0.0
    np.testing.assert_allclose(bias_of(out)[1:], k * 3.0, rtol=1e-9)
    lagged = no_lag.with_effect(EffectSpec("thermal_lag", {"tau_s": 30.0}))
    out = simulate(lagged, t, 0.0, chamber, seed=0)
    # dT_s/dt = r·(1 − e^{−t/τ}): the Shupe-like bias builds up with the lag
    expected = k * 3.0 * (1.0 - np.exp(-t / 30.0))
    np.testing.assert_allclose(bias_of(out)[1:], expected[1:], atol=k * 3.0 * 2e-3)


def test_temp_hysteresis_branches_follow_the_chamber_direction():
    # soak 25, up to 40, soak, down to 10, soak, up to 25, at 0.7 degC/min
    step_c = 0.7 / 60.0 / FS

    def ramp(start, stop):
        k = round(abs(stop - start) / step_c)
        return np.linspace(start, stop, k + 1)[1:]

    seg = [np.full(600, 25.0), ramp(25, 40), np.full(600, 40.0), ramp(40, 10),
           np.full(600, 10.0), ramp(10, 25)]
    chamber = np.concatenate(seg)
    n = len(chamber)
    model = with_effects(base(), ("temp_hysteresis", {"dph": 0.4}))
    _, out = run(model, 0.0, chamber, n)
    # expected from the spec: +1 until the chamber has fallen by more than the band
    # below 40, -1 until it has risen by more than the band above 10, then +1
    fall_start = sum(len(s) for s in seg[:3])
    rise_start = sum(len(s) for s in seg[:5])
    band_samples = math.ceil(HYSTERESIS_BAND_C / step_c)  # 171.4 -> 172nd sample of the ramp
    expected = np.ones(n)
    expected[fall_start + band_samples - 1: rise_start + band_samples - 1] = -1.0
    np.testing.assert_allclose(bias_of(out), 0.4 * expected, atol=1e-12)


def test_temp_hysteresis_ignores_chamber_noise_during_soaks():
    rng = np.random.default_rng(4)
    chamber = np.concatenate([np.full(3000, 25.0), np.linspace(25, 35, 6000), np.full(3000, 35.0),
                              np.linspace(35, 20, 9000), np.full(3000, 20.0)])
    noisy = chamber + rng.uniform(-0.09, 0.09, len(chamber))  # ±0.09 < band/2
    branch, _, _ = hysteresis_sign(noisy)
    assert np.count_nonzero(np.diff(branch)) == 1  # one fall, no chatter in soaks
    assert branch[0] == 1 and branch[-1] == -1
    # the same record in blocks gives the same branch
    parts, sign, extreme = [], 1, None
    for block in np.array_split(noisy, 7):
        h, sign, extreme = hysteresis_sign(block, sign, extreme)
        parts.append(h)
    np.testing.assert_array_equal(np.concatenate(parts), branch)


def test_bias_and_sf_temperature_quadratics():
    model = with_effects(base(), ("bias_temp_quadratic", {"dph_per_c2": 0.002}),
                         ("sf_temp_quadratic", {"ppm_per_c2": 0.3}))
    n = 100
    temp = np.linspace(-40, 80, n)
    rate = np.full(n, 50.0)
    _, out = run(model, rate, temp, n)
    dt = temp - T0
    expected = (1 + 1e-6 * 0.3 * dt**2) * rate + 0.002 * dt**2 / 3600
    np.testing.assert_allclose(out.gyro / SF, expected, rtol=1e-14)


def test_rate_nonlinearities_and_asymmetry():
    model = with_effects(base(), ("sf_nonlinearity_quadratic", {"k2_per_dps": 1e-6}),
                         ("sf_nonlinearity_cubic", {"k3_per_dps2": 2e-9}),
                         ("sf_asymmetry", {"ppm": 300.0}))
    rate = np.array([-300.0, -100.0, -1.0, 0.0, 1.0, 100.0, 300.0])
    _, out = run(model, rate, T0, len(rate))
    expected = rate + 1e-6 * rate**2 + 2e-9 * rate**3 + 0.5e-6 * 300.0 * np.abs(rate)
    np.testing.assert_allclose(out.gyro / SF, expected, rtol=1e-14)
    # sf_asymmetry alone: SF(+) − SF(−) equals the ppm value
    asym = with_effects(base(), ("sf_asymmetry", {"ppm": 300.0}))
    _, out = run(asym, np.array([100.0, -100.0]), T0, 2)
    sf_plus, sf_minus = out.gyro[0] / SF / 100.0, out.gyro[1] / SF / -100.0
    assert (sf_plus - sf_minus) * 1e6 == pytest.approx(300.0, rel=1e-9)


def test_dead_zone_zeroes_table_rate_in_every_rate_term():
    model = with_effects(base(bias_dph=3.6, sf_error_ppm=100.0),
                         ("dead_zone", {"threshold_dps": 0.5}),
                         ("sf_nonlinearity_quadratic", {"k2_per_dps": 1e-3}))
    rate = np.array([-2.0, -0.5, -0.49, 0.0, 0.2, 0.4999, 0.5, 1.0])
    _, out = run(model, rate, T0, len(rate))
    eff = np.where(np.abs(rate) < 0.5, 0.0, rate)
    expected = (1 + 100e-6) * eff + 1e-3 * eff**2 + 3.6 / 3600
    np.testing.assert_allclose(out.gyro / SF, expected, rtol=1e-14)
    assert out.gyro[2] == out.gyro[3] == out.gyro[5]  # inside the band: bias only


def test_rate_saturation_clips_the_summed_rate_terms_each_way():
    model = with_effects(base(bias_dph=3.6, sf_error_ppm=100.0),
                         ("rate_saturation", {"positive_dps": 300.0, "negative_dps": 250.0}))
    rate = np.array([-400.0, -250.0, -200.0, 0.0, 299.0, 300.0, 350.0])
    _, out = run(model, rate, T0, len(rate))
    # (1 + 100 ppm)·ω, clipped to [-250, 300], then the bias: -250 deg/s at -250 already
    expected = np.array([-250.0, -250.0, -200.02, 0.0, 299.0299, 300.0, 300.0]) + 3.6 / 3600
    np.testing.assert_allclose(out.gyro / SF, expected, rtol=1e-12)


def test_warmup_transient_and_bias_ramp_are_functions_of_time():
    model = with_effects(base(), ("warmup_transient", {"amplitude_dph": 5.0, "tau_s": 40.0}),
                         ("bias_ramp", {"dph_per_h": 0.6}))
    n = 2000
    t, out = run(model, 0.0, T0, n)
    np.testing.assert_allclose(bias_of(out), 5.0 * np.exp(-t / 40.0) + 0.6 * t / 3600, rtol=1e-12,
                               atol=1e-13)


def test_table_angle_harmonic_integrates_the_rate_or_uses_the_measured_angle():
    model = with_effects(base(), ("table_angle_harmonic", {"amplitude_dph": 0.7, "phase_deg": 30.0}))
    n = 1000
    t = np.arange(n) / FS
    rate = np.full(n, 12.0)
    out = simulate(model, t, rate, T0, seed=0)
    angle = 12.0 * t  # ∫ω dt from θ(0) = 0
    np.testing.assert_allclose(out.table_angle_deg, angle, atol=1e-9)
    expected = 12.0 + 0.7 * np.cos(np.radians(angle - 30.0)) / 3600
    np.testing.assert_allclose(out.gyro / SF, expected, rtol=1e-14)
    # measured angle wins over the integral
    measured = (100.0 + 12.0 * t) % 360.0
    out = simulate(model, t, rate, T0, seed=0, table_angle_deg=measured)
    np.testing.assert_array_equal(out.table_angle_deg, measured)
    np.testing.assert_allclose(out.gyro / SF, 12.0 + 0.7 * np.cos(np.radians(measured - 30.0)) / 3600,
                               rtol=1e-14)


def test_periodic_interference_is_a_sine_of_time_and_warns_below_nyquist():
    model = with_effects(base(), ("periodic_interference", {"freq_hz": 12.48, "amplitude_dph": 4.0}))
    fs = 200.0
    sim = GyroSimulator(model, fs, seed=0, t0_s=3.0)
    out = sim.generate(0.0, T0, n=500)
    t = 3.0 + np.arange(500) / fs
    np.testing.assert_allclose(out.t_s, t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(bias_of(out), 4.0 * np.sin(2 * np.pi * 12.48 * t), atol=1e-10)
    with pytest.warns(AliasingWarning, match=r"12\.48 Hz .* Nyquist"):
        GyroSimulator(model, 20.0, seed=0)


def test_markov_bias_is_noise_only():
    model = with_effects(base(), ("markov_bias", {"sigma_dph": 2.0, "tau_s": 5.0}))
    _, out = run(model, 0.0, T0, 4000)
    assert not np.any(out.rate_ideal_dps)
    assert np.std(out.noise_dph) == pytest.approx(2.0, rel=0.25)
    np.testing.assert_allclose(out.gyro, SF * out.noise_dph / 3600, rtol=1e-14)
    inputs = ModelInputs.of(np.arange(10.0), 0.0, T0)
    with pytest.raises(ValueError, match="no deterministic rate signature"):
        effect_contribution_dph(model, "markov_bias", inputs)


def test_effect_contribution_isolates_one_effect_including_interactions():
    n = 3000
    t = np.arange(n) / FS
    chamber = 20.0 + 0.05 * t
    model = with_effects(base(bias_dph=1.0, bias_tempco_dph_per_c=0.2),
                         ("thermal_lag", {"tau_s": 60.0}),
                         ("temp_hysteresis", {"dph": 0.3}))
    inputs = ModelInputs.of(t, 0.0, chamber)
    # hysteresis: exactly dph·h(t); with a rising chamber h = +1
    np.testing.assert_allclose(effect_contribution_dph(model, "temp_hysteresis", inputs), 0.3, atol=1e-9)
    # thermal lag acts through the tempco: 0.2·(T_s − T_c)
    lagged = indicated_rate(model, inputs).sensor_temp_c
    np.testing.assert_allclose(effect_contribution_dph(model, "thermal_lag", inputs),
                               0.2 * (lagged - chamber), atol=1e-8)
    with pytest.raises(ValueError, match="has no effect 'dead_zone'"):
        effect_contribution_dph(model, "dead_zone", inputs)
    with pytest.raises(KeyError, match="known effects"):
        effect_contribution_dph(model, "wobble", inputs)


def test_inputs_are_validated_with_the_column_and_sample():
    with pytest.raises(ValueError, match=r"chamber_temp_c: non-finite value nan at sample 2"):
        ModelInputs.of([0.0, 1.0, 2.0], 0.0, [20.0, 20.0, np.nan])
    with pytest.raises(ValueError, match=r"t_s: not strictly increasing at sample 2"):
        ModelInputs.of([0.0, 1.0, 1.0], 0.0, 20.0)
    with pytest.raises(ValueError, match=r"table_rate_dps: expected 3 samples"):
        ModelInputs.of([0.0, 1.0, 2.0], [1.0, 2.0], 20.0)


def test_rate_bandwidth_is_a_first_order_low_pass_continued_across_blocks():
    model = with_effects(base(), ("rate_bandwidth", {"bandwidth_hz": 0.5}))
    t = np.arange(200) / FS
    step = np.where(t >= 1.0, 10.0, 0.0)
    inputs = ModelInputs(t, step, np.full(t.size, T0))
    whole = indicated_rate(model, inputs).rate_dps
    # a step of 10 deg/s through τ = 1/(2π·0.5 Hz) = 0.318 s. The first-order hold makes it a
    # ramp over the sample interval 0.9 → 1.0 s, whose response at its end is
    # 10·(1 − (τ/dt)(1 − e^{−dt/τ})), then decays towards 10 with τ
    tau, dt = 1 / (2 * math.pi * 0.5), 0.1
    later = t >= 1.0
    expected = 10 * (1 - (tau / dt) * -np.expm1(-dt / tau) * np.exp(-(t[later] - 1.0) / tau))
    np.testing.assert_allclose(whole[later], expected, rtol=1e-9)
    first = indicated_rate(model, ModelInputs(t[:120], step[:120], np.full(120, T0)))
    rest = indicated_rate(model, ModelInputs(t[120:], step[120:], np.full(80, T0)), first.state)
    np.testing.assert_allclose(np.concatenate([first.rate_dps, rest.rate_dps]), whole, rtol=1e-12)
