"""The fourth held-out validation set (U1–U3, issue 29) is what it says it is, and cannot drift silently.

``benchmarks/validate_discrepancy_fresh.py --set U`` is meant to be run once,
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
import discrepancy_fresh_u as fresh_u
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

U = fresh_u.SET

#: the runner's default counts for set U (``validate_discrepancy_fresh.SETS["U"]``)
DEFAULT_COUNTS = {"U1": (2, 10, 1, 0), "U2": (3, 45, 2, 1), "U3": (2, 50, 2, 1)}   # seeds, controls, unknowns, near

DESIGN_SHA256 = "a8950af62dcc34cbfa707c94978a2571f760cdc5383caf8932f58765836432d3"
CASES_SHA256 = "433c211845e918152fbc84e1104eab4a9401a42ebbf17307f557bb029196cdf5"
SIZED_CASES_SHA256 = "7548761672725c9075fc38bdf0a4ecd16239698d49941daff0d2a58b25fcab93"

def test_the_set_design_is_pinned():
    """Procedures, unknown shapes (at the first unknown seed) and every parameter of the set."""
    assert digest(design_parts(U)) == DESIGN_SHA256


def test_the_case_list_is_pinned():
    unsized_set = unsized(U)
    cases = default_cases(unsized_set, DEFAULT_COUNTS)
    assert len(cases) == 322
    assert digest([case_key(c, sized=False) for c in cases]) == CASES_SHA256


@pytest.mark.slow
def test_the_case_list_with_its_sizes_is_pinned():
    """Every hidden effect's size to 3 significant digits (the sizing of every catalogue effect, ≈ 10 s)."""
    assert digest([case_key(c, sized=True) for c in default_cases(U, DEFAULT_COUNTS)]) == SIZED_CASES_SHA256


def test_sample_rates_and_durations_are_new_to_every_earlier_set():
    earlier = dict(EARLIER)
    earlier.update({name: fs_and_duration(fresh_r.profile(name)) for name in fresh_r.PROFILES})
    for held in (fresh_s.SET, fresh_t.SET):
        earlier.update({name: fs_and_duration(held.profile(name)) for name in held.profiles})
    assert [fs_and_duration(U.profile(n)) for n in U.profiles] == [(500.0, 720.0), (12.0, 12600.0),
                                                                   (1.25, 54000.0)]
    for name in U.profiles:
        fs_hz, duration_s = fs_and_duration(U.profile(name))
        assert fs_hz not in {fs for fs, _ in earlier.values()}, name
        assert duration_s not in {d for _, d in earlier.values()}, name


def test_seeds_and_shape_streams_are_apart_from_r_s_and_t():
    """Every run of a set is seeded within 600 of its base: the four sets' ranges do not meet."""
    for other in (fresh_r.SET, fresh_s.SET, fresh_t.SET):
        assert abs(U.seed_base - other.seed_base) >= 600 and U.shape_stream != other.shape_stream


def test_unknown_families_are_new_to_every_earlier_set():
    """No family name of R, S or T comes back (the combinations' names carry the family's)."""
    earlier = set(fresh_r.UNKNOWN) | set(fresh_s.UNKNOWN) | set(fresh_t.UNKNOWN)
    assert not earlier & set(U.unknown)
    singles = [n for n, u in U.unknown.items() if not u.with_effect]
    assert len(singles) == 13 and len(U.unknown) - len(singles) == 3


def _held_s(prof: scenarios.Profile) -> dict[float, float]:
    """Seconds spent at each constant non-zero table rate (samples equal to the one before)."""
    rate = prof.table_rate_dps
    steady = np.concatenate([[False], np.diff(rate) == 0.0]) & (rate != 0.0)
    levels, counts = np.unique(rate[steady], return_counts=True)
    return {round(float(r), 9): float(c) / prof.fs_hz for r, c in zip(levels, counts, strict=True)}


def _slope_c_per_min(prof: scenarios.Profile) -> np.ndarray:
    return np.gradient(prof.chamber_temp_c, prof.t_s) * 60.0


def test_u1_is_a_thermal_shock_with_a_new_rung_order_every_cycle():
    prof = U.profile("U1")
    slope = _slope_c_per_min(prof)
    assert slope.max() == pytest.approx(45.0 / (np.e * 90.0) * 60.0, rel=2e-3)       # ΔT/(e·τ), heating
    assert slope.min() < -14.0 and abs(slope[0]) < 1e-9                             # cooling faster; no corner
    assert np.all(np.abs(np.diff(slope)) < 0.01)        # dT/dt continuous: < 0.01 °C/min between samples
    orders = fresh_u.u1_cycles()
    assert len({tuple(r for r, _ in cycle) for cycle in orders}) == len(orders)
    held = _held_s(prof)
    for rung in fresh_u.U1_RUNGS_DPS:                  # every rung, both signs, in every cycle; the 240 deg/s
        for rate in (rung, -rung):                     # rungs lose up to 1.6 s to a slew from −240 or +240
            assert held.get(rate, 0.0) >= len(orders) * 2.3, rate


def test_u2_plateaus_are_not_monotone_and_joined_by_smooth_transitions():
    prof = U.profile("U2")
    levels = fresh_u.U2_PLATEAUS_C
    assert any(np.diff(levels)[i] * np.diff(levels)[i + 1] < 0 for i in range(len(levels) - 2))
    slope = _slope_c_per_min(prof)
    for (start, end, a, b), mean in zip(fresh_u.u2_segments(), fresh_u.U2_MEAN_RAMPS_C_PER_MIN, strict=True):
        inside = (prof.t_s >= start) & (prof.t_s < end)
        assert prof.chamber_temp_c[inside][[0, -1]] == pytest.approx([a, b], abs=1e-3)    # plateau to plateau
        assert np.max(np.abs(slope[inside])) == pytest.approx(0.5 * np.pi * mean, rel=2e-3)
        assert np.all(prof.table_rate_dps[inside & (prof.t_s > start + 1.0)] == fresh_u.U2_TURN_DPS)
    held = _held_s(prof)
    for level in fresh_u.U2_SWEEP_DPS:                 # six plateaus, 12-s dwells less 5-s slews: ±150 once
        visits = 1 if abs(level) == 150.0 else 2           # a sweep, the others twice
        if level != 0.0:
            assert held.get(level, 0.0) == pytest.approx(6 * visits * 7.0, abs=0.2), level


def test_u3_is_static_heavy_in_a_room_day():
    prof = U.profile("U3")
    assert np.mean(prof.table_rate_dps == 0.0) > 0.9
    assert prof.chamber_temp_c.min() > 16.0 and prof.chamber_temp_c.max() < 26.0
    slope = _slope_c_per_min(prof)
    assert np.count_nonzero(np.diff(np.sign(slope)) != 0) == 3          # turns back three times in 1.25 days
    assert slope.max() == pytest.approx(2.0 * -slope.min(), rel=0.1)    # warms up about twice as fast as it cools
    turn = prof.table_rate_dps == 2.0
    assert np.sum(turn) / prof.fs_hz >= 9 * 170.0                        # a full slow turn in every block


def _fit_tools(name: str):
    prof, nominal = U.profile(name), scenarios.nominal_model()
    bins, builder, whitener = scenarios._snr_tools(nominal, prof, NoiseModel.of_model(nominal), MAX_BINS)
    base = scenarios.true_base(nominal)
    return bins, builder, whitener, base, builder.rate_dph(base)


@pytest.mark.parametrize("name", [fresh_u.GIMBAL, fresh_u.PLAY, fresh_u.TILT, fresh_u.HEATER])
def test_binned_unknowns_have_known_shape_snr_10_on_u2(name):
    """√χ² of the base refitted to noise-free base + extra bin means (gls_fit, not the sizing's projection)."""
    bins, builder, whitener, base, base_dph = _fit_tools("U2")
    y = bins.mean(base_dph + U.extra_dph(name, U.profile("U2"), 10.0, U.seed_base + 500))
    assert np.sqrt(gls_fit(builder, whitener, y, base).chi2) == pytest.approx(10.0, rel=0.02)


def test_the_cogging_line_has_norm_10_sigma_and_follows_the_table_angle():
    prof = U.profile("U1")
    name = "line at 24× the table's turn rate (motor cogging, cos 24θ)"
    x = U.extra_dph(name, prof, 10.0, U.seed_base + 501)
    sigma = 60.0 * scenarios.NOMINAL["noise"]["arw_deg_per_rth"] * np.sqrt(prof.fs_hz)
    assert np.linalg.norm(x) / sigma == pytest.approx(10.0, rel=1e-6)
    still = prof.table_rate_dps == 0.0                                  # constant wherever the table stops
    runs = np.flatnonzero(np.diff(still.astype(int)) == 1) + 1
    for start in runs[:5]:
        stop = start + np.argmin(still[start:]) if not still[start:].all() else still.size
        assert np.ptp(x[start:stop]) == pytest.approx(0.0, abs=1e-12)


def test_random_unknowns_differ_between_seeds_and_are_fixed_by_one():
    """The stochastic families draw from the case's shape stream: another seed, another path."""
    prof = U.profile("U2")
    for name in ("random walk advancing only while the table turns",
                 "Gauss–Markov bias whose σ grows with temperature (τ 1/40 of the record)",
                 "narrow-band random bias near a 4-min period (controller hunting)", fresh_u.GIMBAL):
        a, b = (U.extra_dph(name, prof, 10.0, U.seed_base + 500 + k) for k in (0, 1))
        assert not np.allclose(a, b), name
        assert np.array_equal(a, U.extra_dph(name, prof, 10.0, U.seed_base + 500)), name
    walk = fresh_u._turning_random_walk(prof, U.shape_rng(0))
    assert np.all(np.diff(walk)[prof.table_rate_dps[1:] == 0.0] == 0.0)   # still while the table is


@pytest.mark.slow
def test_unknowns_left_out_are_left_out_for_the_reason_given():
    """The backlash leaves < 3σ of 10 beside a catalogue effect on U1 only, the resonance bump on U3 only;
    every other binned unknown run on a profile leaves ≥ 3σ."""
    for pname in U.profiles:
        for name, unknown in U.unknown.items():
            if unknown.sizing != "bins" or unknown.with_effect:
                continue
            signal = U.snr_space(pname).project(unknown.shape(U.profile(pname), U.shape_rng(U.seed_base + 500)))
            signal *= 10.0 / np.linalg.norm(signal)              # unsized: the ratio is what counts
            closest, left = U.closest_catalogue(pname, signal)
            alike = name in U.profiles[pname].catalogue_alike
            assert (left < 3.0) == alike, (pname, name, closest, left)
