"""The fresh held-out validation set (issue 29) is what it says it is.

``benchmarks/validate_discrepancy_fresh.py`` judges the workflow on this set, so
the set itself must be right: each profile runs the procedure its title names
(every commanded dwell rate actually reached through the table's slews), each
out-of-catalogue shape is at the size it claims, measured by a route other than
the one that sized it, controls hold nothing, and no unknown run on a profile is
a catalogue effect there. None of this runs the workflow.
"""

from __future__ import annotations

import functools

import discrepancy_fresh as fresh
import discrepancy_scenarios as scenarios
import numpy as np
import pytest
from scipy.signal import hilbert

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import gls_fit
from gyrocal.models.gyro_sim import simulate


def _held_rates(prof: scenarios.Profile) -> dict[float, float]:
    """Seconds spent at each constant table rate."""
    rates, counts = np.unique(prof.table_rate_dps, return_counts=True)
    return {float(r): float(c) / prof.fs_hz for r, c in zip(rates, counts, strict=True)}


@pytest.mark.parametrize("name, fs_hz, duration_s, dwells_dps, min_held_s", [
    ("R1", 400.0, 2400.0, (2, 20, 50, 100, 150), 6 * 12.0),
    ("R2", 2.0, 21600.0, (0.5, 5, 20, 40, 60), 8 * 30.0),
    ("R3", 1.0, 43200.0, (1, 10, 40, 70, 100), 18 * 30.0),
])
def test_each_profile_holds_every_dwell_rate_of_its_ladder_both_ways(name, fs_hz, duration_s, dwells_dps,
                                                                     min_held_s):
    prof = fresh.profile(name)
    assert prof.fs_hz == pytest.approx(fs_hz)
    assert prof.t_s[-1] + 1.0 / fs_hz == pytest.approx(duration_s)
    held = _held_rates(prof)
    for rate in dwells_dps:
        assert held.get(float(rate), 0.0) >= min_held_s, (name, rate)
        assert held.get(-float(rate), 0.0) >= min_held_s, (name, -rate)


def test_r1_heats_once_from_25_to_45_c_and_slows_half_way():
    prof = fresh.profile("R1")
    temp = prof.chamber_temp_c
    assert temp[0] == 25.0 and temp[-1] == 45.0
    assert np.all(np.diff(temp) >= 0.0)          # one heating ramp, no cooling
    slope_c_per_min = np.gradient(temp, prof.t_s) * 60.0
    assert slope_c_per_min[temp < 34.0].max() == pytest.approx(1.0, rel=1e-6)
    assert slope_c_per_min[(temp > 36.0) & (temp < 44.0)].max() == pytest.approx(0.5, rel=1e-6)


def test_r2_soaks_at_its_staircase_setpoints_for_their_lengths():
    prof = fresh.profile("R2")
    setpoints, _, soaks_s = fresh.R2_STAIRS
    held = _held_rates(scenarios.Profile(prof.t_s, prof.chamber_temp_c, prof.chamber_temp_c))
    for setpoint, soak_s in zip(setpoints, soaks_s, strict=False):
        assert held[setpoint] >= soak_s, setpoint     # 25 °C is visited twice, at least as long


def test_r3_cycles_sinusoidally_between_minus_5_and_45_c():
    temp = fresh.profile("R3").chamber_temp_c
    assert temp.min() == pytest.approx(-5.0, abs=1e-3) and temp.max() == pytest.approx(45.0, abs=1e-3)
    assert np.sum(np.diff(np.sign(np.diff(temp))) != 0) == 6    # three 4-hour cycles: 6 turning points


@functools.cache
def _r2_fit_tools():
    nominal = scenarios.nominal_model()
    prof = fresh.profile("R2")
    bins, builder, whitener = scenarios._snr_tools(nominal, prof, NoiseModel.of_model(nominal), fresh.MAX_BINS)
    base = scenarios.true_base(nominal)
    return bins, builder, whitener, base, builder.rate_dph(base)


def test_each_binned_unknown_has_known_shape_snr_10_on_r2():
    """√χ² of the base refitted to noise-free base + extra bin means (gls_fit, not the sizing's projection)."""
    prof = fresh.profile("R2")
    bins, builder, whitener, base, base_dph = _r2_fit_tools()
    for name, unknown in fresh.UNKNOWN.items():
        if unknown.sizing != "bins" or unknown.with_effect:
            continue
        y = bins.mean(base_dph + fresh.extra_dph(name, prof, 10.0, 9500))
        assert np.sqrt(gls_fit(builder, whitener, y, base).chi2) == pytest.approx(10.0, rel=0.02), name


def test_the_drifting_periodic_term_has_white_noise_snr_10_and_drifts_with_temperature():
    prof = fresh.profile("R3")
    name = "periodic term drifting 0.1 %/°C with temperature"
    x = fresh.extra_dph(name, prof, 10.0, 9500)
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    assert np.linalg.norm(x) / sigma == pytest.approx(10.0, rel=1e-6)
    # its instantaneous frequency (phase of the analytic signal) where the chamber is hottest and coldest
    phase = np.unwrap(np.angle(hilbert(x)))
    freq_hz = np.gradient(phase) * prof.fs_hz / (2.0 * np.pi)
    temp = prof.chamber_temp_c
    ratio = np.median(freq_hz[temp > 44.0]) / np.median(freq_hz[temp < -4.0])
    assert ratio == pytest.approx((1.0 + 1e-3 * 19.0) / (1.0 - 1e-3 * 29.0), abs=0.005)


def test_the_rate_dependent_noise_has_expected_likelihood_ratio_100():
    """The variance-change log-likelihood ratio, averaged over realisations, is snr² = 100."""
    prof = fresh.profile("R2")
    name = "white-noise level growing with |ω|"
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    r = fresh.noise_scale(fresh._rate_noise_shape(prof, None), 10.0) * fresh._rate_noise_shape(prof, None)
    rng = np.random.default_rng(5)
    lrs = []
    for seed in range(8):
        w = sigma * rng.standard_normal(r.size) + fresh.extra_dph(name, prof, 10.0, seed)
        lrs.append(float(np.sum(-np.log1p(r) + (w / sigma) ** 2 * r / (1.0 + r))))
    assert np.mean(lrs) == pytest.approx(100.0, rel=0.25)
    assert np.all(fresh.extra_dph(name, prof, 10.0, 1)[prof.table_rate_dps == 0.0] == 0.0)


def test_random_unknowns_repeat_with_their_seed_and_change_with_another():
    prof = fresh.profile("R2")
    for name in ("two-level telegraph bias (mean dwell 600 s)", "flicker (1/f) excess",
                 "bias random-walk burst at 40–55 % of the record"):
        shape = fresh.UNKNOWN[name].shape
        a, b = shape(prof, fresh.shape_rng(1)), shape(prof, fresh.shape_rng(2))
        assert np.array_equal(a, shape(prof, fresh.shape_rng(1)))
        assert not np.allclose(a, b)


def test_controls_hold_no_effect_and_no_extra_structure():
    cases = fresh.fresh_cases(0, 3, 0, profiles=("R3",))
    controls = [c for c in cases if c.group == "control"]
    assert len(controls) == 3 and len({c.seed for c in controls}) == 3
    prof = fresh.profile("R3")
    for case in controls:
        assert case.hidden == () and fresh.case_extra_dph(case) is None
        logged = scenarios.simulate_log(prof, list(case.hidden), case.seed, extra_dph=fresh.case_extra_dph(case))
        truth = simulate(scenarios.true_base(scenarios.nominal_model()), prof.t_s, prof.table_rate_dps,
                         prof.chamber_temp_c, seed=case.seed)
        assert np.array_equal(logged.gyro, truth.gyro)
        assert not case.is_right("bias_ramp")


@pytest.mark.parametrize("pname", ["R2", "R3"])
def test_no_unknown_run_on_a_profile_is_a_catalogue_effect_there(pname):
    """Every binned unknown run on the profile leaves ≥ 3σ of its 10σ beside its closest catalogue effect."""
    space, prof = fresh.snr_space(pname), fresh.profile(pname)
    for name, unknown in fresh.UNKNOWN.items():
        if unknown.sizing != "bins" or unknown.with_effect or name in fresh.PROFILES[pname].catalogue_alike:
            continue
        signal = space.project(unknown.shape(prof, fresh.shape_rng(9500)))   # unsized: the ratio is what counts
        signal *= 10.0 / np.linalg.norm(signal)
        closest, left = fresh.closest_catalogue(pname, signal)
        assert left >= 3.0, (name, closest, left)
