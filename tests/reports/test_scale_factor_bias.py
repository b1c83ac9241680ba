"""Scale factor, asymmetry, nonlinearity, bias over temperature and compensation tables."""

import math

import numpy as np
import pytest

from gyrocal.analysis.rate.dwell import Dwell, dwell_from_samples, dwell_mean
from gyrocal.analysis.rate.scale_factor import analyze_by_temperature, analyze_scale_factor
from gyrocal.analysis.thermal.bias import (
    bias_by_temperature,
    bias_sensitivity_dph_per_c,
    earth_rate_vertical_dph,
    sf_temperature,
)
from gyrocal.analysis.thermal.compensation import piecewise_linear, polynomial

pytestmark = pytest.mark.timeout(60)


def test_three_rates_by_hand():
    # V(ω) = 2ω + 0.1 + 0.001ω³ at ±10, ±20, ±50 deg/s (no noise).
    rates = [10.0, -10.0, 20.0, -20.0, 50.0, -50.0]
    dwells = [Dwell(25.0, w, 2 * w + 0.1 + 0.001 * w**3) for w in rates]
    result = analyze_scale_factor(dwells)
    # (V+ − V−)/2Ω = 2 + 0.001Ω²: 2.1, 2.4, 4.5
    assert result.sf_by_rate == pytest.approx({10.0: 2.1, 20.0: 2.4, 50.0: 4.5})
    sfs = np.array([2.1, 2.4, 4.5])
    assert result.nonlinearity_rms_pct == pytest.approx(sfs.std(ddof=1) / sfs.mean() * 100)
    # LS slope of an odd cubic over symmetric rates: Σω·V/Σω² = 2 + 0.001·Σω⁴/Σω²
    sum_w2, sum_w4 = 2 * (100 + 400 + 2500), 2 * (1e4 + 16e4 + 625e4)
    assert result.sf == pytest.approx(2 + 0.001 * sum_w4 / sum_w2)
    assert result.bias == pytest.approx(0.1)
    # residual ω(0.001ω² − 2.14) at 10, 20, 50: −20.4, −34.8, +18 → max 34.8 at 20 deg/s,
    # full scale 4.14·50 = 207.
    assert result.sf == pytest.approx(4.14)
    assert result.nonlinearity_max_ppm_fs == pytest.approx(34.8 / 207.0 * 1e6)
    # Odd nonlinearity is symmetric: no asymmetry.
    assert result.asymmetry_ppm == pytest.approx(0.0, abs=1e-6)


def test_asymmetry_from_separate_fits_by_hand():
    # SF+ = 1.0002, SF− = 0.9998, bias 0.5 with rates ±10, ±30.
    dwells = []
    for w in (10.0, 30.0):
        dwells.append(Dwell(20.0, w, 1.0002 * w + 0.5))
        dwells.append(Dwell(20.0, -w, 0.9998 * -w + 0.5))
    result = analyze_scale_factor(dwells)
    assert result.sf_plus == pytest.approx(1.0002, rel=1e-12)
    assert result.sf_minus == pytest.approx(0.9998, rel=1e-12)
    assert result.asymmetry_ppm == pytest.approx(0.0004 / 1.0 * 1e6, rel=1e-9)
    assert result.to_json() == {"temp_c": 20.0, "sf": result.sf, "sf_plus": result.sf_plus,
                                "sf_minus": result.sf_minus}


def test_single_rate_pair_gives_chikovani_sf_and_unobservable_asymmetry():
    result = analyze_scale_factor([Dwell(-40.0, 50.0, 101.0), Dwell(-40.0, -50.0, -99.0)])
    assert result.sf == pytest.approx((101.0 - -99.0) / 100.0)
    assert result.sf_plus == pytest.approx(2.0)
    assert result.sf_minus == pytest.approx(2.0)
    assert result.asymmetry_ppm == pytest.approx(0.0, abs=1e-6)
    assert result.bias == pytest.approx(1.0)


def _model_output(rate_dps, temp_c, rng, n=2000, fs=100.0):
    """gyro-model.md equation with sf_tempco, bias tempco, asymmetry, cubic NL and noise."""
    scale, t0 = 2.0, 25.0
    s_ppm = 50.0 + 20.0 * (temp_c - t0)
    b_dph = 2.0 + 0.03 * (temp_c - t0) + earth_rate_vertical_dph(52.0)
    nl = 0.5e-6 * 300.0 * abs(rate_dps) + 2e-9 * rate_dps**3
    noise_dph = rng.standard_normal(n) * 0.01 * 60 * math.sqrt(fs)  # ARW 0.01 deg/√h
    indicated = (1 + 1e-6 * s_ppm) * rate_dps + nl + (b_dph + noise_dph) / 3600.0
    return scale * indicated


def test_recovers_a_known_model_over_rate_and_temperature():
    rng = np.random.default_rng(42)
    temps = [-10.0, 5.0, 20.0, 30.0, 40.0]  # the vendor's calibration points
    rates = [10.0, 50.0, 100.0, 200.0, 300.0]
    dwells = [dwell_from_samples(t, s * w, _model_output(s * w, t, rng), 100.0, settle_s=0.0)
              for t in temps for w in rates for s in (1, -1)]
    per_temp = analyze_by_temperature(dwells)
    assert [r.temp_c for r in per_temp] == temps
    for r in per_temp:
        assert r.asymmetry_ppm == pytest.approx(300.0, abs=5.0)
        expected_sf = 2.0 * (1 + 1e-6 * (50.0 + 20.0 * (r.temp_c - 25.0)))
        # cubic NL adds 2e-9·Σω⁴/Σω² ≈ 1.5e-4 to the LS slope (output units: ×2)
        w = np.array(rates)
        cubic_slope = 2 * 2e-9 * np.sum(w**4) / np.sum(w**2)
        assert r.sf == pytest.approx(expected_sf + cubic_slope, rel=2e-6)
    sf_t = sf_temperature(per_temp, reference_temp_c=25.0)
    assert sf_t.sensitivity_ppm_per_c == pytest.approx(20.0, rel=0.01)
    sfs = np.array([r.sf for r in per_temp])
    assert sf_t.instability_pct == pytest.approx(sfs.std(ddof=1) / sfs.mean() * 100)

    bias = bias_by_temperature(per_temp, latitude_deg=52.0)
    # |ω| asymmetry term biases the intercept by 0.5e-6·300·mean|ω|: remove it from the truth.
    asym_dph = 0.5e-6 * 300.0 * np.mean(rates) * 3600.0
    for point in bias:
        truth = 2.0 + 0.03 * (point.temp_c - 25.0) + asym_dph
        assert point.bias_dph == pytest.approx(truth, abs=0.2)
    assert bias_sensitivity_dph_per_c(bias) == pytest.approx(0.03, abs=0.005)
    assert bias[0].to_json() == {"temp_c": -10.0, "bias_dph": bias[0].bias_dph}


def test_earth_rate_component():
    assert earth_rate_vertical_dph(90.0) == pytest.approx(15.041067)
    assert earth_rate_vertical_dph(30.0) == pytest.approx(15.041067 / 2)
    with pytest.raises(ValueError, match="latitude"):
        earth_rate_vertical_dph(95.0)


def test_dwell_mean_trims_settling_and_whole_revolutions():
    fs, rate = 100.0, 36.0  # one revolution = 10 s = 1000 samples
    t = np.arange(3500) / fs
    angle_deg = rate * t
    samples = 5.0 + np.cos(np.radians(angle_deg))  # table-angle harmonic
    samples[:200] = 1e3  # settling transient
    whole = dwell_mean(samples, fs, settle_s=2.0, rate_dps=rate, revolutions="all")
    assert whole.n_samples == 3000
    assert whole.mean == pytest.approx(5.0, abs=1e-12)
    raw = dwell_mean(samples, fs, settle_s=2.0)
    assert raw.n_samples == 3300 and abs(raw.mean - 5.0) > 1e-3
    assert dwell_mean(samples, fs, 2.0, rate, revolutions=2).n_samples == 2000
    with pytest.raises(ValueError, match="3 whole revolution"):
        dwell_mean(samples, fs, 2.0, rate, revolutions=4)
    with pytest.raises(ValueError, match="non-zero rate"):
        dwell_mean(samples, fs, 2.0, revolutions=1)


def test_piecewise_table_reports_leave_one_out_residual_by_hand():
    temps = [-10.0, 5.0, 20.0, 30.0, 40.0]
    values = [1.0, 2.0, 2.5, 4.0, 4.5]
    table = piecewise_linear(temps, values)
    assert table.to_pairs() == [[t, v] for t, v in zip(temps, values, strict=True)]
    # LOO: -10 from (5,2),(20,2.5) → 2 − 15·(0.5/15) = 1.5, residual −0.5
    #        5 from (−10,1),(20,2.5) → 1.75, residual 0.25
    #       20 from (5,2),(30,4) → 3.2, residual −0.7
    #       30 from (20,2.5),(40,4.5) → 3.5, residual 0.5
    #       40 from (20,2.5),(30,4) → 5.5, residual −1.0
    loo = np.array([-0.5, 0.25, -0.7, 0.5, -1.0])
    assert table.loo_residual_rms == pytest.approx(np.sqrt(np.mean(loo**2)))
    assert table.loo_residual_max == pytest.approx(1.0)
    assert table.evaluate(12.5) == pytest.approx(2.25)
    assert table.evaluate(50.0) == pytest.approx(5.0)


def test_polynomial_compensation_recovers_a_quadratic_law():
    temps = np.array([-40.0, -10.0, 5.0, 20.0, 30.0, 40.0, 75.0])
    values = 3.0 + 0.02 * temps - 4e-4 * temps**2
    table = polynomial(temps, values, degree=2)
    np.testing.assert_allclose(table.coefficients, [-4e-4, 0.02, 3.0], atol=1e-12)
    assert table.residual_rms < 1e-12 and table.loo_residual_rms < 1e-10
    linear = polynomial(temps, values, degree=1)
    assert linear.loo_residual_rms > linear.residual_rms > 0.1
    # The piecewise table on the same curved law leaves a visible LOO error.
    assert piecewise_linear(temps, values).loo_residual_rms > 0.05


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="temperatures"):
        analyze_scale_factor([Dwell(20.0, 1.0, 1.0), Dwell(30.0, -1.0, -1.0)])
    with pytest.raises(ValueError, match="both signs"):
        analyze_scale_factor([Dwell(20.0, 1.0, 1.0), Dwell(20.0, 2.0, 2.0)])
    with pytest.raises(ValueError, match="duplicate temperature"):
        piecewise_linear([1.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="at least 4"):
        polynomial([1.0, 2.0, 3.0], [0.0, 1.0, 2.0], degree=2)


def test_a_flat_output_gives_undefined_figures_not_a_crash():
    """Regression: a gyro stuck at full scale (``gyro.saturate:always``) crashed the report
    with ZeroDivisionError. Its scale factor is 0 and the relative figures are NaN."""
    dwells = [Dwell(25.0, w, 400.0) for w in (10.0, -10.0, 50.0, -50.0)]
    result = analyze_scale_factor(dwells)
    assert result.sf == pytest.approx(0.0, abs=1e-12)
    assert math.isnan(result.asymmetry_ppm)
    assert math.isnan(result.nonlinearity_rms_pct)
