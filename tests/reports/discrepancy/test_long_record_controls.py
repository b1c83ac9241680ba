"""Effect-free controls on a long, low-rate record stay explained (issue 29).

The second held-out set's first run called 5 of 40 effect-free controls of a
20-hour, 2.5 Hz record `unexplained`; 3 of them with a ``where`` naming a slow
probe ("segment means in time since power-on"). On our own profile of that kind
(``discrepancy_long_record``: 20 h, 2.5 Hz, a plateau temperature cycle) the
rule that reads G1 against its effect-free distribution fired on 2 of 100
controls: its 0.99 point was the largest of 60 simulated residuals, which an
effect-free G1 exceeds with probability 1/61, and whose value wandered
0.87–1.37 between runs. g1_null.py gives the exact point (G1 is a χ²-weighted
sum); known truth here: a covariance of our own with a slow process, and
effect-free simulated records.
"""

from __future__ import annotations

import discrepancy_scenarios as scenarios
import numpy as np
import pytest
from discrepancy_long_record import long_record_profile

from gyrocal.analysis.discrepancy.g1_null import g1_quantile, g1_weights
from gyrocal.analysis.discrepancy.gap import SegmentGeometry, g1
from gyrocal.analysis.discrepancy.scoring import Whitener

N_BINS = 300
N_DRAWS = 6000


def _slow_geometry() -> tuple[Whitener, np.ndarray, SegmentGeometry]:
    """Bin means with white noise and a slow Gauss–Markov part (τ a third of the record), uneven
    segments, and a refit of a bias, a ramp and a step: a long record's G1 in small."""
    k = np.arange(N_BINS, dtype=float)
    lag = np.abs(k[:, None] - k[None, :])
    cov = np.eye(N_BINS) + 0.05 * np.exp(-lag / 100.0) + 0.2 * np.exp(-lag / 3.0)
    whitener = Whitener(cov)
    columns = np.column_stack([np.ones(N_BINS), k / N_BINS, (k > 170).astype(float)])
    basis = np.linalg.qr(whitener.white(columns))[0]
    edges = np.cumsum(np.random.default_rng(4).integers(2, 12, size=60))
    seg = np.searchsorted(edges[edges < N_BINS], k, side="right")
    return whitener, basis, SegmentGeometry.of(seg, cov)


def test_the_g1_point_is_exceeded_by_one_percent_of_effect_free_residuals():
    whitener, basis, geometry = _slow_geometry()
    z = np.random.default_rng(29).standard_normal((N_BINS, N_DRAWS))
    null = g1(geometry, whitener.colour(z - basis @ (basis.T @ z)))
    # the weights carry G1's exact mean: Σλ/n_seg against the simulated mean (its standard error)
    weights = g1_weights(whitener, basis, geometry)
    assert abs(weights.sum() - null.mean()) < 4.0 * null.std() / np.sqrt(N_DRAWS)
    point = g1_quantile(whitener, basis, geometry, 0.99)
    exceed = int(np.sum(null > point))
    # binomial(6000, 1 %): mean 60, sd 7.7; the former rule (largest of 60) would give ~98
    assert 35 <= exceed <= 85, exceed
    assert 0.08 < np.mean(null > g1_quantile(whitener, basis, geometry, 0.9)) < 0.12


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_long_low_rate_controls_are_not_unexplained(seed):
    """8 h of the long-record profile (its shape, shorter plateaus): nothing named, nothing left."""
    result = scenarios.analyse_scenario(long_record_profile(8.0), [], seed)
    assert result.found == []
    assert not result.unexplained, result.where
    assert any("the white-noise level is steady" in note for note in result.notes)


def test_the_control_the_sixty_draw_point_called_unexplained_is_explained():
    """Seed 1006 of the 20-hour profile: G1 0.990 was above the largest of 60 draws (0.969) and the
    record was called unexplained ("segment means follow time since power-on"); the exact 0.99
    point is 1.05."""
    result = scenarios.analyse_scenario(long_record_profile(20.0), [], 1006)
    assert result.found == []
    assert 0.95 < result.metrics["g1_segment_mean"].after < 1.05
    assert not result.unexplained, result.where
