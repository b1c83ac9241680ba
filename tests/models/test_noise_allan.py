"""Each noise term checked by its IEEE 952 Allan signature, allantools as the oracle.

The estimator is allantools.oadev on rate ("freq") data in deg/h; the targets
are the closed forms of IEEE Std 952 Annex C with the unit conversions of
gyrocal.models.noise (N·60 deg/h·√s, K/60 deg/h/√s, R/3600 deg/h/s).
Tolerances follow the estimator's own scatter for the record lengths used.
"""

from __future__ import annotations

import math
from pathlib import Path

import allantools
import numpy as np
import pytest

from gyrocal.models.gyro_model import NoiseParams, load_model
from gyrocal.models.noise import (
    FLICKER_FLOOR_PER_B,
    FlickerNoise,
    GaussMarkov,
    NoiseGenerator,
    RateRamp,
    RateRandomWalk,
    WhiteAngleNoise,
    WhiteRateNoise,
    markov_allan_variance,
)

pytestmark = pytest.mark.timeout(60)


def adev_dph(rate_dph: np.ndarray, fs_hz: float, taus_s) -> tuple[np.ndarray, np.ndarray]:
    taus, adev, _err, _n = allantools.oadev(rate_dph, rate=fs_hz, data_type="freq", taus=list(taus_s))
    return np.asarray(taus), np.asarray(adev)


@pytest.mark.parametrize("seed", [1, 2])
def test_white_rate_noise_gives_arw_at_one_second(seed):
    arw_deg_per_rth = 0.01
    fs = 50.0
    rate = WhiteRateNoise(arw_deg_per_rth, fs, seed).generate(200_000)  # 4000 s
    taus, adev = adev_dph(rate, fs, [1.0, 10.0])
    # σ(τ=1 s) in deg/h equals N in deg/h·√s = 60·N[deg/√h]; slope −1/2.
    assert adev[0] / 60.0 == pytest.approx(arw_deg_per_rth, rel=0.04)
    assert adev[1] * math.sqrt(10.0) / 60.0 == pytest.approx(arw_deg_per_rth, rel=0.08)


def test_white_angle_noise_gives_root3_q_over_tau():
    q_arcsec = 0.72
    fs = 100.0
    rate = WhiteAngleNoise(q_arcsec, fs, 3).generate(40_000)
    taus, adev = adev_dph(rate, fs, [0.01, 0.03, 0.1, 0.3])
    # arcsec/s == deg/h, so σ(τ) = √3·Q/τ directly in deg/h with Q in arcsec.
    np.testing.assert_allclose(adev, math.sqrt(3.0) * q_arcsec / taus, rtol=0.04)


def test_rate_random_walk_gives_k_root_tau_over_3():
    k_dph_per_rth = 2.0
    fs = 10.0
    rate = RateRandomWalk(k_dph_per_rth, fs, 4).generate(200_000)  # 20000 s
    taus, adev = adev_dph(rate, fs, [10.0, 30.0, 100.0])
    expected = (k_dph_per_rth / 60.0) * np.sqrt(taus / 3.0)
    np.testing.assert_allclose(adev, expected, rtol=0.08)


@pytest.mark.parametrize("seed", [5, 6])
def test_rate_ramp_gives_r_tau_over_root2(seed):
    r_dph_per_h = 3.0
    fs = 10.0
    rate = RateRamp(r_dph_per_h, fs, seed).generate(50_000)
    taus, adev = adev_dph(rate, fs, [1.0, 10.0, 100.0, 1000.0])
    # deterministic ramp of ±R/3600 deg/h per s: exact for any draw.
    np.testing.assert_allclose(adev, (r_dph_per_h / 3600.0) * taus / math.sqrt(2.0), rtol=1e-6)


def test_flicker_bank_gives_bias_instability_floor():
    b_dph = 0.05
    fs = 10.0
    rate = FlickerNoise(b_dph, fs, 7).generate(300_000)  # 30000 s
    taus, adev = adev_dph(rate, fs, np.logspace(0.5, 2.5, 9))  # 3 .. 300 s
    ratio = adev / (FLICKER_FLOOR_PER_B * b_dph)
    assert abs(FLICKER_FLOOR_PER_B - 0.664) < 5e-4  # sqrt(2 ln2 / pi)
    assert np.median(ratio) == pytest.approx(1.0, abs=0.05)
    assert np.all(np.abs(ratio - 1.0) < 0.12), ratio
    # flat: no white (−1/2) or random-walk (+1/2) slope over two decades
    slope = np.polyfit(np.log10(taus), np.log10(adev), 1)[0]
    assert abs(slope) < 0.06


def test_gauss_markov_hump_sits_at_1_89_tau_with_height_0_62_sigma():
    sigma_dph, tau_s, fs = 1.0, 50.0, 5.0
    rate = GaussMarkov(sigma_dph, tau_s, fs, 8).generate(400_000)  # 80000 s = 1600 tau
    assert np.std(rate) == pytest.approx(sigma_dph, rel=0.05)
    taus, adev = adev_dph(rate, fs, np.logspace(1, 3, 41))
    peak_tau = taus[np.argmax(adev)]
    assert 0.75 * 1.89 * tau_s < peak_tau < 1.3 * 1.89 * tau_s
    # IEEE 952: peak Allan deviation of exponentially correlated noise ≈ 0.618·σ
    assert adev.max() == pytest.approx(0.618 * sigma_dph, rel=0.08)


@pytest.mark.parametrize(
    "make",
    [
        lambda s: WhiteRateNoise(0.1, 100.0, s),
        lambda s: WhiteAngleNoise(1.0, 100.0, s),
        lambda s: RateRandomWalk(1.0, 100.0, s),
        lambda s: RateRamp(1.0, 100.0, s),
        lambda s: GaussMarkov(1.0, 0.5, 100.0, s),
        lambda s: FlickerNoise(0.1, 100.0, s),
    ],
    ids=["N", "Q", "K", "R", "markov", "B"],
)
def test_each_term_streams_exactly(make):
    whole = make(11).generate(5000)
    gen = make(11)
    parts = np.concatenate([gen.generate(n) for n in (1, 999, 0, 2500, 1500)])
    np.testing.assert_allclose(parts, whole, rtol=1e-12, atol=1e-12)


def test_noise_generator_sums_independent_streams():
    fs = 100.0
    only_n = NoiseGenerator(NoiseParams(arw_deg_per_rth=0.1), fs, seed=3).generate(1000)
    both = NoiseGenerator(NoiseParams(arw_deg_per_rth=0.1, rrw_deg_per_h_rth=0.0), fs, seed=3,
                          markov=(1.0, 10.0))
    assert set(both.terms) == {"N", "markov"}
    n_term = both.terms["N"].generate(1000)
    np.testing.assert_array_equal(n_term, only_n)  # adding a term never changes another's draws
    silent = NoiseGenerator(NoiseParams(), fs, seed=3)
    assert silent.terms == {} and not np.any(silent.generate(10))


def test_vg951d_published_figures_reproduce_its_allan_curve():
    """The VG951D model file against the published Chikovani figures (seeds/000)."""
    model = load_model(Path(__file__).resolve().parents[2] / "gyro-models" / "vg951d.yaml")
    markov = model.effect("markov_bias")
    fs = 2.0
    gen = NoiseGenerator(model.noise, fs, seed=12, markov=(markov["sigma_dph"], markov["tau_s"]))
    rate = gen.generate(400_000)  # 200000 s
    taus, adev = adev_dph(rate, fs, [1.0, 10.0, 1000.0])
    q, n_rth, b = 18.0, 0.25 * 60.0, 0.25
    expected = np.sqrt(3 * q**2 / taus**2 + n_rth**2 / taus + (FLICKER_FLOOR_PER_B * b) ** 2
                       + markov_allan_variance(taus, markov["sigma_dph"], markov["tau_s"]))
    np.testing.assert_allclose(adev, expected, rtol=0.1)
    # the Markov part alone peaks at the published 0.7 deg/h near 1000 s
    hump = np.sqrt(markov_allan_variance(1.89 * 528.0, markov["sigma_dph"], markov["tau_s"]))
    assert hump == pytest.approx(0.7, abs=0.01)
