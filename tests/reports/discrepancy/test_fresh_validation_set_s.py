"""The second held-out validation set (S1–S3, issue 29) is what it says it is.

``benchmarks/validate_discrepancy_fresh.py --set S`` judges the workflow on this
set, so the set must be right: each profile runs the procedure its title names
and is unlike the profiles of the earlier sets, each out-of-catalogue shape is at
the size it claims (measured by a route other than the one that sized it),
controls hold nothing, and an unknown left out of a profile is left out for the
reason given. None of this runs the workflow.
"""

from __future__ import annotations

import functools

import discrepancy_fresh as fresh_r
import discrepancy_fresh_s as fresh_s
import discrepancy_scenarios as scenarios
import numpy as np
import pytest
from discrepancy_heldout import MAX_BINS, noise_scale
from scipy.signal import hilbert

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import gls_fit

S = fresh_s.SET

#: (sample rate Hz, duration s) of the sets the workflow has been tuned or judged on:
#: P1–P3 (benchmarks/validate_discrepancy.py ``profile``), Q1–Q3 (validate_discrepancy_outside.py
#: ``PROFILES``); R1–R3 are built below from their own module
EARLIER = {"P1": (5.0, 3600.0), "P2": (100.0, 9300.0), "P3": (200.0, 7200.0),
           "Q1": (20.0, 5400.0), "Q2": (50.0, 2700.0), "Q3": (10.0, 10800.0)}


def _fs_and_duration(prof: scenarios.Profile) -> tuple[float, float]:
    return round(prof.fs_hz, 6), round(prof.t_s[-1] + 1.0 / prof.fs_hz, 3)


def _held_s(prof: scenarios.Profile) -> dict[float, float]:
    """Seconds spent at each constant non-zero table rate (samples equal to the one before)."""
    rate = prof.table_rate_dps
    steady = np.concatenate([[False], np.diff(rate) == 0.0]) & (rate != 0.0)
    levels, counts = np.unique(rate[steady], return_counts=True)
    return {float(r): float(c) / prof.fs_hz for r, c in zip(levels, counts, strict=True)}


def test_sample_rates_and_durations_are_new_to_every_earlier_set():
    earlier = dict(EARLIER)
    earlier.update({name: _fs_and_duration(fresh_r.profile(name)) for name in fresh_r.PROFILES})
    assert _fs_and_duration(S.profile("S1")) == (1000.0, 780.0)
    assert _fs_and_duration(S.profile("S2")) == (25.0, 6000.0)
    assert _fs_and_duration(S.profile("S3")) == (2.5, 72000.0)
    for name in S.profiles:
        fs_hz, duration_s = _fs_and_duration(S.profile(name))
        assert fs_hz not in {fs for fs, _ in earlier.values()}, name
        assert duration_s not in {d for _, d in earlier.values()}, name


def test_s1_climbs_the_ladder_cold_and_descends_it_hot():
    prof = S.profile("S1")
    held = _held_s(prof)
    for rate in fresh_s.S1_LADDER_DPS:               # every rung both ways, at least a second after each slew
        assert held.get(rate, 0.0) >= 2.0 and held.get(-rate, 0.0) >= 2.0, rate
    temp, moving = prof.chamber_temp_c, prof.table_rate_dps != 0.0
    assert set(np.unique(temp[moving])) == {-15.0, 55.0}          # the table turns in the soaks only
    first_cold = prof.t_s[moving & (temp < 0.0) & (np.abs(prof.table_rate_dps) == 300.0)][0]
    first_hot = prof.t_s[moving & (temp > 0.0) & (np.abs(prof.table_rate_dps) == 0.1)][0]
    assert first_cold > prof.t_s[moving & (temp < 0.0) & (np.abs(prof.table_rate_dps) == 0.1)][0]
    assert first_hot > prof.t_s[moving & (temp > 0.0) & (np.abs(prof.table_rate_dps) == 300.0)][0]
    slope = np.abs(np.gradient(temp, prof.t_s)) * 60.0
    assert slope.max() == pytest.approx(20.0, rel=1e-6)


def test_s2_only_sweeps_on_one_slow_ramp():
    prof = S.profile("S2")
    assert _held_s(prof) == {}                                    # no rate is ever held
    assert prof.table_rate_dps.max() == pytest.approx(250.0) and prof.table_rate_dps.min() == pytest.approx(-250.0)
    accel = np.abs(np.diff(prof.table_rate_dps)) * prof.fs_hz
    assert accel.max() <= 2.0 + 1e-6
    slope = np.gradient(prof.chamber_temp_c, prof.t_s) * 60.0
    ramp = (prof.t_s > 301.0) & (prof.t_s < 5699.0)
    assert np.allclose(slope[ramp], 50.0 / 90.0)
    assert prof.chamber_temp_c[0] == 0.0 and prof.chamber_temp_c[-1] == 50.0


def test_s3_turns_the_table_in_its_plateaus_only_with_the_ladder_up_and_down():
    prof = S.profile("S3")
    temp, moving = prof.chamber_temp_c, prof.table_rate_dps != 0.0
    assert temp.min() == -25.0 and temp.max() == 65.0
    assert len(fresh_s.s3_plateau_starts_s()) == 8
    assert np.all(np.gradient(temp, prof.t_s)[moving] == 0.0)
    held = _held_s(prof)
    for rate in fresh_s.S3_LADDER_DPS:         # 90-s dwells less the slews, twice per ladder (once at the top)
        dwells = 8 * (1 if rate == max(fresh_s.S3_LADDER_DPS) else 2)
        assert held.get(rate, 0.0) >= dwells * 78.0 and held.get(-rate, 0.0) >= dwells * 78.0, rate


@functools.cache
def _s3_fit_tools():
    prof, nominal = S.profile("S3"), scenarios.nominal_model()
    bins, builder, whitener = scenarios._snr_tools(nominal, prof, NoiseModel.of_model(nominal), MAX_BINS)
    base = scenarios.true_base(nominal)
    return bins, builder, whitener, base, builder.rate_dph(base)


@pytest.mark.parametrize("name", [fresh_s.SHUPE_T, fresh_s.SF_HYSTERESIS, "bias re-drawn at each of four power cycles",
                                  "asymmetric telegraph bias (mean dwells 1 % and 8 % of the record)"])
def test_binned_unknowns_have_known_shape_snr_10_on_s3(name):
    """√χ² of the base refitted to noise-free base + extra bin means (gls_fit, not the sizing's projection)."""
    bins, builder, whitener, base, base_dph = _s3_fit_tools()
    y = bins.mean(base_dph + S.extra_dph(name, S.profile("S3"), 10.0, 19500))
    assert np.sqrt(gls_fit(builder, whitener, y, base).chi2) == pytest.approx(10.0, rel=0.02)


def test_the_drifting_line_has_white_noise_snr_10_and_rises_3_percent():
    prof = S.profile("S3")
    x = S.extra_dph("line at 0.21·fs drifting +3 % over the record", prof, 10.0, 19500)
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    assert np.linalg.norm(x) / sigma == pytest.approx(10.0, rel=1e-6)
    freq_hz = np.gradient(np.unwrap(np.angle(hilbert(x)))) * prof.fs_hz / (2.0 * np.pi)
    tenth = prof.t_s.size // 10
    start, end = np.median(freq_hz[tenth:2 * tenth]), np.median(freq_hz[-2 * tenth:-tenth])
    assert start == pytest.approx(0.21 * 2.5 * 1.0045, rel=2e-3)
    assert end / start == pytest.approx(1.0255 / 1.0045, rel=2e-3)


@pytest.mark.parametrize("name", ["white-noise level growing with temperature",
                                  "intermittent noise bursts (0.4 % of the record each)"])
def test_noise_level_unknowns_have_expected_likelihood_ratio_100(name):
    """The variance-change log-likelihood ratio, averaged over realisations, is snr² = 100."""
    prof = S.profile("S3")
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    rng = np.random.default_rng(11)
    lrs = []
    for seed in range(4):
        shape = S.unknown[name].shape(prof, S.shape_rng(seed))          # the same draw extra_dph makes
        r = noise_scale(shape, 10.0) * shape
        w = sigma * rng.standard_normal(r.size) + S.extra_dph(name, prof, 10.0, seed)
        lrs.append(float(np.sum(-np.log1p(r) + (w / sigma) ** 2 * r / (1.0 + r))))
    assert np.mean(lrs) == pytest.approx(100.0, rel=0.25)


def test_rate_history_shapes_follow_the_ladder_and_are_the_scale_factor_itself_on_sweeps():
    s3, s2 = S.profile("S3"), S.profile("S2")
    rng = S.shape_rng(1)
    h = fresh_s._sf_rate_hysteresis(s3, rng)
    ladder = s3.t_s < fresh_s.s3_plateau_starts_s()[1]              # the first plateau's ladder
    at_8 = ladder & (s3.table_rate_dps == 8.0)
    first_half = s3.t_s < s3.t_s[at_8].mean()
    assert np.all(h[at_8 & first_half] == 8.0) and np.all(h[at_8 & ~first_half] == -8.0)   # up, then down
    settling = fresh_s._sf_settling(s3, rng)
    steady = (s3.table_rate_dps == 250.0)
    assert settling[steady].max() > 0.9 * 250.0 and settling[steady].min() < 1e-6 * 250.0
    for shape in (fresh_s._sf_rate_hysteresis, fresh_s._sf_settling):
        assert np.allclose(shape(s2, rng), s2.table_rate_dps)           # why S2 does not run them
    assert set(S.profiles["S2"].not_applicable) == set(fresh_s.NO_DWELLS)


def test_controls_hold_nothing_and_the_seeds_are_apart_from_the_first_set():
    cases = S.cases(0, 50, 0, profiles=("S3",))
    assert [c.group for c in cases] == ["control"] * 50
    assert all(c.hidden == () and S.case_extra_dph(c) is None for c in cases)
    r_controls = {c.seed for c in fresh_r.fresh_cases(0, 50, 0, profiles=("R3",))}
    assert not r_controls & {c.seed for c in cases}
    # every run of a set is seeded within 600 of its base (effects, Markov, dead zone, quantization,
    # controls, unknowns: + 0, 100, …, 500 + k, k < 100): the two sets' ranges do not meet
    assert abs(S.seed_base - fresh_r.SET.seed_base) >= 600 and S.shape_stream != fresh_r.SET.shape_stream
    run_on_s1 = [n for n in S.unknown if S.profiles["S1"].runs_unknown(n)]
    assert len(run_on_s1) == len(S.unknown) - 2          # the slow sine is nearly bias_ramp in 13 minutes
    run_on_s2 = [n for n in S.unknown if S.profiles["S2"].runs_unknown(n)]
    assert len(run_on_s2) == len(S.unknown) - 3          # no held rate: the rate-history shapes


def test_no_unknown_run_on_s2_is_a_catalogue_effect_there():
    """Every binned unknown run on S2 leaves ≥ 3σ of its 10σ beside its closest catalogue effect."""
    space, prof = S.snr_space("S2"), S.profile("S2")
    checked = 0
    for name, unknown in S.unknown.items():
        if unknown.sizing != "bins" or unknown.with_effect or not S.profiles["S2"].runs_unknown(name):
            continue
        signal = space.project(unknown.shape(prof, S.shape_rng(19500)))   # unsized: the ratio is what counts
        signal *= 10.0 / np.linalg.norm(signal)
        closest, left = S.closest_catalogue("S2", signal)
        assert left >= 3.0, (name, closest, left)
        checked += 1
    assert checked == 6
