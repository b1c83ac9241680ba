"""The third held-out validation set (T1–T3, issue 29) is what it says it is, and cannot drift silently.

``benchmarks/validate_discrepancy_fresh.py --set T`` is meant to be run once,
at the end, against a workflow nobody tuned on this set. Its worth is that it
stays the set it was when it was made: the digests below pin its procedures,
its out-of-catalogue shapes, its parameters and its case list (and, in the slow
test, every hidden effect's size), so a change to any of them fails here and
has to be made on purpose, with the digest. The other tests check the set says
what it does. None of this runs the workflow.
"""

from __future__ import annotations

import discrepancy_fresh as fresh_r
import discrepancy_fresh_s as fresh_s
import discrepancy_fresh_t as fresh_t
import discrepancy_scenarios as scenarios
import numpy as np
import pytest
from discrepancy_heldout import MAX_BINS
from heldout_pinning import (
    EARLIER,
    case_key,
    default_cases,
    design_parts,
    digest,
    fs_and_duration,
    unsized,
)

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import gls_fit

T = fresh_t.SET

#: the runner's default counts for set T (``validate_discrepancy_fresh.SETS["T"]``)
DEFAULT_COUNTS = {"T1": (2, 10, 1, 0), "T2": (3, 50, 2, 1), "T3": (2, 45, 2, 1)}   # seeds, controls, unknowns, near

DESIGN_SHA256 = "8a38f895b39eb46f843d96a8a0ee536d2ae14d333e0c393414afe7ba0834fbae"
CASES_SHA256 = "8c3da032007e3a91c1d04182fa1ff6fd1b9d305ca0653189b7c4fb8dfae3d6a9"
SIZED_CASES_SHA256 = "848a054f5d157098d7fdc39399601163aad53578fe51dad537c5bb551e4484fa"

def test_the_set_design_is_pinned():
    """Procedures, unknown shapes (at the first unknown seed) and every parameter of the set."""
    assert digest(design_parts(T)) == DESIGN_SHA256


def test_the_case_list_is_pinned():
    unsized_set = unsized(T)
    cases = default_cases(unsized_set, DEFAULT_COUNTS)
    assert len(cases) == 318
    assert digest([case_key(c, sized=False) for c in cases]) == CASES_SHA256


@pytest.mark.slow
def test_the_case_list_with_its_sizes_is_pinned():
    """Every hidden effect's size to 3 significant digits (the sizing of every catalogue effect, ≈ 25 s)."""
    assert digest([case_key(c, sized=True) for c in default_cases(T, DEFAULT_COUNTS)]) == SIZED_CASES_SHA256


def test_sample_rates_and_durations_are_new_to_every_earlier_set():
    earlier = dict(EARLIER)
    earlier.update({name: fs_and_duration(fresh_r.profile(name)) for name in fresh_r.PROFILES})
    earlier.update({name: fs_and_duration(fresh_s.SET.profile(name)) for name in fresh_s.PROFILES})
    assert [fs_and_duration(T.profile(n)) for n in T.profiles] == [(250.0, 1500.0), (8.0, 18000.0),
                                                                   (4.0, 32400.0)]
    for name in T.profiles:
        fs_hz, duration_s = fs_and_duration(T.profile(name))
        assert fs_hz not in {fs for fs, _ in earlier.values()}, name
        assert duration_s not in {d for _, d in earlier.values()}, name


def test_seeds_and_shape_streams_are_apart_from_r_and_s():
    """Every run of a set is seeded within 600 of its base: the three sets' ranges do not meet."""
    for other in (fresh_r.SET, fresh_s.SET):
        assert abs(T.seed_base - other.seed_base) >= 600 and T.shape_stream != other.shape_stream


def _held_s(prof: scenarios.Profile) -> dict[float, float]:
    """Seconds spent at each constant non-zero table rate (samples equal to the one before)."""
    rate = prof.table_rate_dps
    steady = np.concatenate([[False], np.diff(rate) == 0.0]) & (rate != 0.0)
    levels, counts = np.unique(rate[steady], return_counts=True)
    return {round(float(r), 9): float(c) / prof.fs_hz for r, c in zip(levels, counts, strict=True)}


def test_t1_runs_an_unequal_ladder_through_the_sine_and_winds_up_then_unwinds():
    prof = T.profile("T1")
    held = _held_s(prof)
    for plus, minus in zip(fresh_t.T1_POSITIVE_DPS, fresh_t.T1_NEGATIVE_DPS, strict=True):
        for rate in (plus, minus, -plus, -minus):   # flipped in the last four cycles; ≥ 1.5 s held after each
            assert held.get(round(rate, 9), 0.0) >= 4 * 1.5, rate   # slew (the top rungs' slews take 3.9 s)
    assert max(held) == pytest.approx(0.55 * 2.5 ** 7) and min(held) == pytest.approx(-0.55 * 2.5 ** 7)
    turns = np.cumsum(prof.table_rate_dps) / prof.fs_hz / 360.0
    wound = turns[prof.t_s < fresh_t.T1_CYCLE_STARTS_S[fresh_t.T1_MIRRORED_FROM]][-1]
    assert wound < -5.0 and abs(turns[-1]) < 0.25 * abs(wound)
    slope = np.gradient(prof.chamber_temp_c, prof.t_s) * 60.0
    assert slope.max() == pytest.approx(2.0 * np.pi * 15.0 / 12.5, rel=1e-3)


def test_t2_staircase_is_asymmetric_with_dwells_in_soaks_and_ramps():
    prof = T.profile("T2")
    slope = np.round(np.gradient(prof.chamber_temp_c, prof.t_s) * 60.0, 9)
    assert set(np.unique(slope[slope != 0.0])) >= {4.0, -0.4, -3.0, 0.5}
    held = _held_s(prof)
    for rate in (7.0, -23.0, 61.0):                                    # five soaks, 60-s dwells less the slews
        assert held.get(rate, 0.0) >= 5 * 55.0, rate
    for rate in (15.0, -40.0):                                         # four ramps
        assert held.get(rate, 0.0) >= 4 * 115.0, rate
        dwell = (prof.table_rate_dps == rate) & np.concatenate([[False], np.diff(prof.table_rate_dps) == 0.0])
        assert np.all(slope[dwell] != 0.0)                              # the pair runs while T moves
    assert prof.table_rate_dps.max() == 180.0 and prof.table_rate_dps.min() == -120.0


def test_t3_is_static_heavy_on_one_ramp_a_hot_soak_and_a_cool_back():
    prof = T.profile("T3")
    assert np.mean(prof.table_rate_dps == 0.0) > 0.85
    slope = np.round(np.diff(prof.chamber_temp_c) * prof.fs_hz * 60.0, 9)
    assert set(np.unique(slope[slope != 0.0])) == {0.2, -1.0}
    assert prof.chamber_temp_c.max() == 70.0 and prof.chamber_temp_c[-1] == 25.0
    turn = prof.table_rate_dps == 1.0                                   # a full slow turn in every block
    assert np.sum(turn) / prof.fs_hz >= 7 * 360.0


def _fit_tools(name: str):
    prof, nominal = T.profile(name), scenarios.nominal_model()
    bins, builder, whitener = scenarios._snr_tools(nominal, prof, NoiseModel.of_model(nominal), MAX_BINS)
    base = scenarios.true_base(nominal)
    return bins, builder, whitener, base, builder.rate_dph(base)


@pytest.mark.parametrize("name", [fresh_t.SF_DTDT, fresh_t.OVERSHOOT, "bias ∝ net table turns (cable wind-up)",
                                  fresh_t.COMPRESSOR])
def test_binned_unknowns_have_known_shape_snr_10_on_t2(name):
    """√χ² of the base refitted to noise-free base + extra bin means (gls_fit, not the sizing's projection)."""
    bins, builder, whitener, base, base_dph = _fit_tools("T2")
    y = bins.mean(base_dph + T.extra_dph(name, T.profile("T2"), 10.0, T.seed_base + 500))
    assert np.sqrt(gls_fit(builder, whitener, y, base).chi2) == pytest.approx(10.0, rel=0.02)


@pytest.mark.parametrize("name", ["five single-sample outliers (Laplace values)",
                                  "line at 0.37·fs with amplitude ∝ |ω|"])
def test_white_sized_unknowns_have_norm_10_sigma(name):
    prof = T.profile("T3")
    x = T.extra_dph(name, prof, 10.0, T.seed_base + 501)
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    assert np.linalg.norm(x) / sigma == pytest.approx(10.0, rel=1e-6)
    if "outliers" in name:
        assert np.count_nonzero(x) == 5
    else:                                              # nothing while the table is still
        assert not np.any(x[prof.table_rate_dps == 0.0]) and np.any(x)


@pytest.mark.slow
def test_unknowns_left_out_are_left_out_for_the_reason_given():
    """No setpoint is ever reached on T1's sine; ω·dT/dt leaves < 3σ of 10 beside thermal_lag on T1 and T3
    (≥ 3σ on T2, where it runs); every other binned unknown run on a profile leaves ≥ 3σ."""
    t1 = T.profile("T1")
    assert not np.any(fresh_t._chamber_overshoot(t1, T.shape_rng(0)))
    for pname in T.profiles:
        for name, unknown in T.unknown.items():
            if unknown.sizing != "bins" or unknown.with_effect or name in T.profiles[pname].not_applicable:
                continue
            signal = T.snr_space(pname).project(unknown.shape(T.profile(pname), T.shape_rng(T.seed_base + 500)))
            signal *= 10.0 / np.linalg.norm(signal)              # unsized: the ratio is what counts
            closest, left = T.closest_catalogue(pname, signal)
            alike = name in T.profiles[pname].catalogue_alike
            assert (left < 3.0) == alike, (pname, name, closest, left)
