"""Localized and impulsive structure: window scan (localized.py) and harmonic comb (harmonic_comb.py), issue 29.

On the fifth held-out set 1-s pulses every 90 s were not seen on two profiles and named
periodic_interference at ≥ 0.8 on a third, and a few random bias steps were named
bias_temp_quadratic at ≥ 0.8. The cases here are this test's own (shapes, sizes, profile,
seeds), sized by known-shape SNR (``scenarios.sized_extra``). Before the two tests the pulse
train below went unseen (no claim, not ``unexplained``), the random steps were ``unexplained``
as a two-level switching bias, and the P1 bump was named markov_bias at 1.00
(docs/discrepancy-validation.md, "Localized and impulsive structure").
"""

from __future__ import annotations

import functools
import math
import re

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy import harmonic_comb, localized
from gyrocal.analysis.discrepancy.scoring import Whitener
from gyrocal.analysis.discrepancy.segments import make_bins

MAX_BINS = 1000


@functools.lru_cache(maxsize=1)
def few_level_profile() -> scenarios.Profile:
    """45 min at 50 Hz, 25 → 60 → 5 → 25 °C at 5 °C/min, ±0.2, 3, 20, 300 deg/s at 50 deg/s²."""
    return scenarios.procedure_profile(2700.0, 50.0, setpoints_c=(25.0, 60.0, 5.0, 25.0),
                                       ramps_c_per_min=(5.0, 5.0, 5.0), rates_dps=(0.2, 3.0, 20.0, 300.0),
                                       dwell_s=15.0, static_s=60.0, slow_rate_dps=6.0, accel_dps2=50.0)


def test_window_variances_are_the_refit_residuals_own():
    """The prefix-sum variances equal aᵀ(C − LQ(LQ)ᵀ)a computed window by window."""
    rng = np.random.default_rng(1)
    n = 64
    a = rng.standard_normal((n, n))
    cov = a @ a.T / n + np.eye(n)
    chol = np.linalg.cholesky(cov)
    basis, _ = np.linalg.qr(np.linalg.solve(chol, np.column_stack([np.ones(n), np.arange(n)])))
    w = localized.windows(n, cov, chol @ basis)
    resid_cov = chol @ (np.eye(n) - basis @ basis.T) @ chol.T
    for i in rng.choice(w.start.size, 25, replace=False):
        box = np.zeros(n)
        box[w.start[i]:w.stop[i]] = 1.0
        assert w.variance[i] == pytest.approx(box @ resid_cov @ box, rel=1e-9)
    assert w.stop.max() - w.start.min() <= n and (w.stop - w.start).max() <= localized.MAX_SHARE * n


def _null_exceedance(test_max, threshold: float, n: int, basis: np.ndarray, draws: int) -> int:
    z = np.random.default_rng(77).standard_normal((n, draws))
    return int(np.sum(test_max(z - basis @ (basis.T @ z)) > threshold))


def test_both_thresholds_hold_their_level_on_fresh_null_draws():
    """Thresholds extrapolated from 200 draws, checked on 6000 fresh ones: the window scan's α is
    0.25 % (15 expected), the comb's 0.1 % (6); a threshold read off the draws' own 90 % point would
    let ~600 through."""
    n = 300
    chol = np.linalg.cholesky(np.eye(n) + 3.0 * np.exp(-np.abs(np.subtract.outer(np.arange(n), np.arange(n))) / 20.0))
    basis, _ = np.linalg.qr(np.linalg.solve(chol, np.column_stack([np.ones(n), np.linspace(-1, 1, n)])))
    rate, innov = localized.windows(n, chol @ chol.T, chol @ basis), localized.windows(n, None, basis)

    def window_max(z: np.ndarray) -> np.ndarray:
        return np.maximum(localized.window_z2(chol @ z, rate).max(axis=0), localized.window_z2(z, innov).max(axis=0))

    null = localized.projected_draws(n, basis)
    x = localized.family_threshold(window_max(null), localized._chi2_1_tail, 2 * rate.start.size,
                                   localized.ALPHA_LOCALIZED)
    assert _null_exceedance(window_max, x, n, basis, 6000) <= 32
    comb_x = harmonic_comb.comb_threshold(null, harmonic_comb.n_trials(n))

    def comb_max(z: np.ndarray) -> np.ndarray:
        return harmonic_comb._scores(harmonic_comb._periodogram(z, harmonic_comb.PAD * n), n)[0]

    assert _null_exceedance(comb_max, comb_x, n, basis, 6000) <= 32


def _white_case(signal: np.ndarray, seed: int = 5):
    n = signal.size
    t = np.arange(n, dtype=float)
    bins = make_bins(t, 1.0, max_bins=n)
    basis = np.ones((n, 1)) / math.sqrt(n)
    r = signal + np.random.default_rng(seed).standard_normal(n)
    r = r - basis[:, 0] * (basis[:, 0] @ r)
    return r, basis, bins


def test_the_comb_sees_a_pulse_train_and_not_a_sinusoid_of_the_same_size():
    n = 1200
    t = np.arange(n, dtype=float)
    pulses = ((t - 17.0) % 60.0 < 3.0).astype(float)
    pulses *= 12.0 / np.linalg.norm(pulses - pulses.mean())
    sine = np.sin(2.0 * math.pi * t / 60.0)
    sine *= 12.0 / np.linalg.norm(sine)
    r, basis, bins = _white_case(pulses)
    found = harmonic_comb.comb(r, r, basis, bins)
    assert found.fires and found.period_s == pytest.approx(60.0, rel=0.01)
    assert "a pulse train" in found.describe()
    r, basis, bins = _white_case(sine)
    assert not harmonic_comb.comb(r, r, basis, bins).fires


def test_the_window_scan_places_a_burst():
    n = 1200
    burst = np.zeros(n)
    burst[700:730] = 1.0
    burst *= 9.0 / np.linalg.norm(burst)
    r, basis, bins = _white_case(burst)
    whitener = Whitener(np.eye(n))
    found = localized.scan(r, r, whitener, basis, bins)
    assert found.fires
    start, stop, mean, _z, _innov = found.spans_s[0]
    assert 680 <= start <= 710 and 720 <= stop <= 750 and mean > 0


def claims(result) -> list[tuple[str, float]]:
    return [(f.name, round(f.probability, 3)) for f in result.found]


@pytest.mark.parametrize(("seed", "shape", "words"), [
    (31500, "pulses", ("not a sinusoid", "pulse train")),
    (31501, "steps", ("localized bias structure",)),
])
def test_own_localized_cases_are_unexplained_with_where_and_no_claim(seed, shape, words):
    """6-s pulses every 150 s, and four bias steps of random sign, each at 10σ on the 45-min profile:
    ``unexplained``, ``where`` says what, no catalogue name ≥ 0.8."""
    prof = few_level_profile()
    t = prof.t_s - prof.t_s[0]
    if shape == "pulses":
        raw = ((t - 40.0) % 150.0 < 6.0).astype(float)
    else:
        rng = np.random.default_rng(seed)
        raw = sum(sign * (t >= at) for at, sign in zip(rng.uniform(0.1, 0.9, 4) * t[-1],
                                                        rng.choice((-1.0, 1.0), 4), strict=True))
    extra = scenarios.sized_extra(raw, 10.0, prof, max_bins=MAX_BINS)
    result = scenarios.analyse_scenario(prof, [], seed, extra_dph=extra)
    assert result.unexplained, claims(result)
    assert all(w in result.where for w in words), result.where
    assert not [c for c in claims(result) if c[1] >= 0.8], (claims(result), result.where)


def test_a_bump_a_markov_bias_took_is_unexplained_and_the_markov_claim_falls():
    """A raised-cosine bump (FWHM 108 s at 2268 s) at 10σ on the 1-h 5 Hz profile, seed 31001: before the
    window scan it was named markov_bias at 1.00; the innovations show a jump the process does not make."""
    prof = scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)
    u = np.clip(((prof.t_s - prof.t_s[0]) / 3600.0 - 0.63) / 0.03, -1.0, 1.0)
    extra = scenarios.sized_extra(0.5 * (1.0 + np.cos(np.pi * u)), 10.0, prof, max_bins=MAX_BINS)
    result = scenarios.analyse_scenario(prof, [], 31001, extra_dph=extra)
    assert result.unexplained and "localized bias structure" in result.where, (claims(result), result.where)
    assert not [c for c in claims(result) if c[1] >= 0.8], claims(result)
    spans = [float(x) for x in re.findall(r"over t = (\d+)–(\d+) s", result.where)[0]]
    assert spans[0] < 2268.0 < spans[1]


def test_an_effect_free_record_leaves_both_tests_quiet_and_says_so():
    result = scenarios.analyse_scenario(few_level_profile(), [], 31502)
    assert not result.unexplained, result.where
    assert any("(localized.py)" in n and n.startswith("no localized") for n in result.notes)
    assert any("(harmonic_comb.py)" in n and n.startswith("no periodic") for n in result.notes)
