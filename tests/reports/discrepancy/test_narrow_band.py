"""A narrow-band random bias (a peaked spectrum): unexplained, described, never markov_bias at ≥ 0.8.

On the fourth held-out set a narrow-band random bias near a 4-min period was
neither named nor called unexplained on two of its three profiles; on our own
cases the search named markov_bias at 1.0 (a Lorentzian has no peak, but it
was the only random reading the catalogue had). narrow_band.py holds a
second-order Gauss–Markov reading against the catalogue's (noise model, Markov
bias, a line) by Whittle's likelihood. The cases are our own: centre 0.0037 Hz,
Q 4 on the 1-hour, 5 Hz profile P1 of validate_discrepancy.py, sized 10σ by the
known-shape SNR of its binned shape.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import discrepancy_scenarios as scenarios
import numpy as np
import pytest
from scipy.signal import lfilter

from gyrocal.analysis.discrepancy.narrow_band import narrow_band_test
from gyrocal.analysis.discrepancy.stochastic import WhittleTest, fine_bins

MAX_BINS = 1000


@functools.lru_cache(maxsize=1)
def p1() -> scenarios.Profile:
    return scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)


def narrow_band(prof: scenarios.Profile, f0_hz: float, q: float, size: float, seed: int) -> np.ndarray:
    """A second-order Gauss–Markov realization (AR(2), poles r·e^(±iω0/fs), r = e^(−ω0/(2Q·fs))), at SNR ``size``."""
    fs = prof.fs_hz
    w0 = 2.0 * math.pi * f0_hz
    r = math.exp(-w0 / (2.0 * q * fs))
    warm = int(20.0 * q / f0_hz * fs)
    x = lfilter([1.0], [1.0, -2.0 * r * math.cos(w0 / fs), r * r],
                np.random.default_rng(seed).standard_normal(len(prof.t_s) + warm))[warm:]
    return scenarios.sized_extra(x, size, prof, max_bins=MAX_BINS)


def _claims(result) -> list[tuple[str, float]]:
    return [(f.name, round(f.probability, 3)) for f in result.found]


def _band(ctx, fit):
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    noise = replace(ctx.noise, markov_sigma_dph=0.0, markov_tau_s=0.0)
    return narrow_band_test(WhittleTest(noise, bins, ctx.fs_hz), bins.mean(ctx.resid_full(fit)))


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", [1, 2])
def test_a_narrow_band_random_bias_is_unexplained_and_described(seed):
    """Seed 2 named markov_bias at 1.0 before the test."""
    prof = p1()
    result = scenarios.analyse_scenario(prof, [], seed, max_bins=MAX_BINS,
                                        extra_dph=narrow_band(prof, 0.0037, 4.0, 10.0, seed + 11))
    assert result.unexplained
    assert all(p < 0.8 for _, p in _claims(result)), _claims(result)
    assert result.where.startswith("a random bias in a narrow band around 0.00"), result.where
    f0 = float(result.where.split("around ")[1].split(" Hz")[0])
    assert 0.0030 <= f0 <= 0.0045, result.where


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", [21, 22])
def test_the_band_is_read_back(seed):
    """The test alone on the base refit: centre within 15 %, Q between 2 and 8 for a Q-4 process."""
    prof = p1()
    ctx, fit = scenarios.base_refit(prof, seed, extra_dph=narrow_band(prof, 0.005, 4.0, 12.0, seed))
    band = _band(ctx, fit)
    assert band.fires, band
    assert band.f0_hz == pytest.approx(0.005, rel=0.15)
    assert 2.0 <= band.q <= 8.0


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("tau_s", "seed"), [(30.0, 31), (300.0, 32), (None, 33)])
def test_a_true_markov_bias_or_nothing_is_not_a_narrow_band(tau_s, seed):
    """The catalogue's Lorentzian at 10σ (unnamed in the base refit) and an effect-free record stay below the limit."""
    prof = p1()
    hidden = [] if tau_s is None else [scenarios.sized_markov(10.0, tau_s, prof)]
    ctx, fit = scenarios.base_refit(prof, seed, hidden)
    band = _band(ctx, fit)
    assert not band.fires, band
    if tau_s is not None:
        assert band.catalogue == "a Markov bias"


@pytest.mark.timeout(120)
def test_a_true_markov_bias_is_still_named_first():
    prof = p1()
    result = scenarios.analyse_scenario(prof, [scenarios.sized_markov(10.0, 30.0, prof)], 41, max_bins=MAX_BINS)
    assert result.found and result.found[0].name == "markov_bias", _claims(result)
    assert result.found[0].probability >= 0.8
    assert "narrow band" not in result.where
