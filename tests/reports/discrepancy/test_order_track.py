"""A line locked to the table angle (motor cogging, order k ≥ 2): unexplained, described, never a claim ≥ 0.8.

On the fourth held-out set a cogging line cos 24θ at 10σ was neither named nor
called unexplained on two of its three profiles: its frequency in time is
k·|ω|/360, a different one in every rate dwell, which the fixed-line and
drifting-line searches do not follow, and table_angle_harmonic is order 1 only.
order_track.py reads the residual against the table angle in every turning
dwell and pools the dwells coherently. The cases here are our own: orders 24
and 36 at phases 200° and 75° on the 45-min, 50 Hz profile Q2 of
validate_discrepancy_outside.py, sized by their norm against the white noise
over the samples where the table turns.
"""

from __future__ import annotations

import functools
import math

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.order_track import ORDER_ALPHA, OrderPlan, order_scan
from gyrocal.models.indicated import input_history

MAX_BINS = 1000


@functools.lru_cache(maxsize=1)
def q2() -> scenarios.Profile:
    """45 min at 50 Hz, soaks at 25/60/5/25 °C, ±0.2…300 deg/s dwells of 15 s, 50 deg/s² (Q2)."""
    return scenarios.procedure_profile(2700.0, 50.0, setpoints_c=(25.0, 60.0, 5.0, 25.0),
                                       ramps_c_per_min=(5.0, 5.0, 5.0), rates_dps=(0.2, 3.0, 20.0, 300.0),
                                       dwell_s=15.0, static_s=60.0, slow_rate_dps=6.0, accel_dps2=50.0)


def angle_line(prof: scenarios.Profile, order: int, phase_deg: float, size: float) -> np.ndarray:
    """cos(k·θ − φ), ‖s‖ = size·σ of the nominal white noise over the samples where the table turns."""
    theta = input_history(prof.inputs).angle_deg
    shape = np.cos(np.deg2rad(order * theta - phase_deg))
    sigma = NoiseModel.of_model(scenarios.nominal_model()).white_sigma_dph(prof.fs_hz)
    return size * sigma * shape / np.linalg.norm(shape[np.abs(prof.table_rate_dps) > 0])


def _claims(result) -> list[tuple[str, float]]:
    return [(f.name, round(f.probability, 3)) for f in result.found]


def _scan(ctx, fit, extra: np.ndarray | None = None):
    resid = ctx.resid_full(fit) if extra is None else extra
    return order_scan(resid, ctx.builder.history.angle_deg, ctx.log.table_rate_dps, ctx.segments.slices,
                      ctx.fs_hz, ctx.noise)


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("order", "phase_deg", "seed"), [(24, 200.0, 6100), (24, 200.0, 6101), (36, 75.0, 6102)])
def test_a_line_locked_to_the_table_angle_is_unexplained_and_described(order, phase_deg, seed):
    """Seed 6100 named markov_bias at 1.0 before the Markov reading was judged without the line."""
    prof = q2()
    result = scenarios.analyse_scenario(prof, [], seed, max_bins=MAX_BINS,
                                        extra_dph=angle_line(prof, order, phase_deg, 10.0))
    assert result.unexplained
    assert all(p < 0.8 for _, p in _claims(result)), _claims(result)
    assert result.where.startswith(f"a line locked to the table angle at order {order} "), result.where
    phase = float(result.where.split(f"cos({order}θ − ")[1].split("°")[0])
    assert abs((phase - phase_deg + 180.0) % 360.0 - 180.0) < 20.0, result.where


def test_the_order_spectrum_reads_amplitude_and_phase_on_both_rate_signs():
    """Noise-free: a line cos(24θ − 200°) of 0.5 deg/h in dwells at ±3, ±20 deg/s is read back exactly."""
    fs = 50.0
    rate = np.concatenate([np.full(1500, 3.0), np.zeros(100), np.full(1000, -20.0), np.zeros(100),
                           np.full(800, 20.0), np.full(700, -3.0)])
    theta = np.cumsum(rate) / fs + 17.0
    resid = 0.5 * np.cos(np.deg2rad(24.0 * theta - 200.0))
    edges = np.flatnonzero(np.diff(rate)) + 1
    slices = [slice(int(a), int(b)) for a, b in zip(np.r_[0, edges], np.r_[edges, rate.size], strict=True)]
    line = order_scan(resid, theta, rate, slices, fs, NoiseModel(arw_deg_per_rth=0.01))
    assert line.order == 24
    assert line.amplitude_dph == pytest.approx(0.5, rel=0.02)
    assert line.phase_deg == pytest.approx(200.0, abs=1.0)
    assert line.n_dwells == 4 and line.rates_dps == (3.0, 20.0)


@pytest.mark.timeout(600)
def test_effect_free_white_noise_fires_at_the_stated_rate():
    """200 draws of the nominal white noise through Q2's turning dwells: the max over every order tested
    passes the 0.5 % threshold about once (Poisson: ≤ 4 at the 99.6 % point), and its median is that of
    the max of as many independent Exp(1) (the bound is not loose by more than a little).

    The draws are scanned by one ``OrderPlan`` of Q2's dwells (the residual-free set-up made once:
    ~0.007 s a draw against 0.07 s), which gives ``order_scan``'s line bit for bit (asserted on
    the first draw)."""
    prof = q2()
    ctx, _ = scenarios.base_refit(prof, 1)
    noise = NoiseModel.of_model(scenarios.nominal_model())
    rng = np.random.default_rng(5)
    sigma = noise.white_sigma_dph(prof.fs_hz)
    plan = OrderPlan.of(ctx.builder.history.angle_deg, prof.table_rate_dps, ctx.segments.slices,
                        prof.fs_hz, noise)
    fires, powers = 0, []
    for k in range(200):
        draw = sigma * rng.standard_normal(len(prof.t_s))
        line = plan.scan(draw)
        if k == 0:
            assert line == order_scan(draw, ctx.builder.history.angle_deg, prof.table_rate_dps,
                                      ctx.segments.slices, prof.fs_hz, noise)
        fires += line.fires
        powers.append(line.power)
    assert fires <= 4
    # the max of K Exp(1) has median ln K − ln ln 2: the bound is not loose by more than a little
    assert np.median(powers) == pytest.approx(math.log(line.n_orders) + 0.37, abs=1.0)
    assert ORDER_ALPHA == 0.005


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", [6110, 6111, 6112])
def test_effect_free_records_are_silent(seed):
    result = scenarios.analyse_scenario(q2(), [], seed, max_bins=MAX_BINS)
    assert "a line locked to the table angle" not in result.where
    assert not result.found, _claims(result)


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("name", "seed"), [("table_angle_harmonic", 6120), ("periodic_interference", 6121)])
def test_the_catalogues_angle_and_time_lines_are_still_named_first(name, seed):
    """Order 1 is table_angle_harmonic's; a fixed line in time has no phase relation to θ across dwells."""
    prof = q2()
    spec = scenarios.sized_effect(name, 10.0, prof, max_bins=MAX_BINS)
    result = scenarios.analyse_scenario(prof, [spec], seed, max_bins=MAX_BINS)
    assert result.found and result.found[0].name == name, _claims(result)
    assert result.found[0].probability >= 0.8
    assert "a line locked to the table angle" not in result.where
