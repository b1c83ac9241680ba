"""The effect-free distribution of G1 after the refit, exactly, for the "unexplained" rule.

``workflow._gap_pass`` calls a record unexplained when G1 over every segment
(gap.py: the mean of (segment mean / its standard error)²) is above the
``UNEXPLAINED_LEVEL`` = 0.99 point of its effect-free distribution. That point
was read off the 60 simulated residuals the gap metrics share: the
⌈0.99·61⌉-th of 60 values is their maximum, so an effect-free record was called
unexplained with probability 1/61 = 1.6 %, not 1 %, and the maximum of 60
draws of a distribution this skewed (slow noise makes G1 a sum of few large
χ² terms on a long record) wanders: its 0.99 point ranged 0.87–1.37 over 100
controls of one 20-hour, 2.5 Hz profile, where G1 itself has mean 0.68 and
standard deviation 0.13. On that profile 2 of 100 controls were called
unexplained by this rule alone, with ``where`` naming whatever probe was
strongest ("segment means follow time since power-on").

G1 of the refitted residual under the noise model is a quadratic form in a
standard normal vector: the residual is L(I − QQᵀ)z (L the bin covariance's
Cholesky factor, Q the whitened fitted columns' orthonormal basis), the
segment means are Sᵀ of it, so G1 = |D^½ Sᵀ L (I − QQᵀ) z|² / n_seg with D
the inverse squared standard errors. Its distribution is Σ λ_i χ²₁ / n_seg
over the eigenvalues λ_i of the n_seg × n_seg matrix
D^½ SᵀL(I − QQᵀ)LᵀS D^½, and its quantile is drawn from that sum
(``N_DRAWS`` draws of n_seg independent χ²₁, no residual to colour). Cost: one
sparse pass over L's rows per segment and an n_seg² eigenproblem, about 0.01 s
on 1000 bins and 172 segments, and 0.03 s of draws.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from gyrocal.analysis.discrepancy.gap import SegmentGeometry
from gyrocal.analysis.discrepancy.scoring import Whitener, order_statistic_quantile

#: Draws of the weighted χ² sum the quantile is read from: at 0.99, 10 000 draws put the
#: probability beyond the point within 0.99–1.1 % (one standard error 0.1 %).
N_DRAWS = 10000
#: Seed of the quadrature draws.
QUADRATURE_SEED = 29
#: The largest weights drawn as χ²₁ terms; the rest by the normal limit of their sum.
N_EXACT = 300
#: Chunk of draws generated at once (bounds the memory to N_CHUNK × n_seg doubles).
N_CHUNK = 2000


def g1_weights(whitener: Whitener, basis: np.ndarray, geometry: SegmentGeometry) -> np.ndarray:
    """The λ_i / n_seg whose χ²₁-weighted sum is G1 of an effect-free refitted residual."""
    # Sᵀ L: each segment's average of L's rows (averaging is n_bins × n_seg, one bin in one segment)
    sl = sparse.csr_array(geometry.averaging.T) @ whitener.chol
    slq = sl @ basis
    scale = 1.0 / geometry.stderr_dph
    cov = (sl @ sl.T - slq @ slq.T) * np.outer(scale, scale)
    eig = np.linalg.eigvalsh(0.5 * (cov + cov.T))
    return np.clip(eig, 0.0, None) / len(scale)


def g1_quantile(whitener: Whitener, basis: np.ndarray, geometry: SegmentGeometry, level: float) -> float:
    """The ``level`` point of G1 on effect-free refitted residuals (see the module docstring).

    The draws are a numerical integration of a known distribution, not a null of the data, so
    they come from their own fixed-seed generator: the workflow's own stream (the other tests'
    null draws) is left as it was.
    """
    rng = np.random.default_rng(QUADRATURE_SEED)
    weights = g1_weights(whitener, basis, geometry)
    # the largest weights as χ²₁ draws; the many small ones by their sum's normal limit (its exact
    # mean and variance), so a record of thousands of segments costs no more than one of N_EXACT
    order = np.argsort(weights)[::-1]
    big, small = weights[order[:N_EXACT]], weights[order[N_EXACT:]]
    draws = np.concatenate([np.square(rng.standard_normal((min(N_CHUNK, N_DRAWS - start), len(big)))) @ big
                            for start in range(0, N_DRAWS, N_CHUNK)])
    draws += small.sum() + np.sqrt(2.0 * float(small @ small)) * rng.standard_normal(N_DRAWS)
    return order_statistic_quantile(draws, level)
