"""Generalised least squares on bin means, and the likelihood gain of every candidate effect.

The noise of a gyro is correlated (flicker, Markov, random walk), so an
ordinary least-squares χ² or a plain BIC counts the same slow wander many
times over and "finds" effects that are not there. Here every quantity is
computed after whitening by the Cholesky factor L of the noise covariance of
the bin means (C = L·Lᵀ): a candidate's score is the drop of the whitened χ²
(twice the log-likelihood gain) when it is added to the refitted model.

For the threshold calibration the same whitened designs are reused: effect-
free data from the refitted model plus noise drawn from the noise model are,
after whitening, the refitted prediction plus standard normal vectors Z, so
every candidate's null score is a few projections of Z (see
:func:`null_delta_chi2`) and hundreds of simulated datasets cost less than
one refit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats
from scipy.linalg import cholesky, qr, solve_triangular

from gyrocal.analysis.discrepancy.signatures import (
    PHASED,
    STRUCTURAL,
    Column,
    Design,
    DesignBuilder,
    SearchSpace,
    apply_coefficients,
    dead_zone_candidates,
    dead_zone_neighbourhood,
    placeholder_spec,
    searched_effects,
    shape_grid,
)
from gyrocal.models.gyro_model import EffectSpec, GyroModel

_LN10 = math.log(10.0)


class Whitener:
    """x ↦ L⁻¹x for the bin-mean noise covariance C = L·Lᵀ."""

    def __init__(self, covariance: np.ndarray) -> None:
        jitter = 1e-12 * float(np.mean(np.diag(covariance)))
        self.chol = cholesky(covariance + jitter * np.eye(len(covariance)), lower=True,
                             check_finite=False)
        self.covariance = covariance

    def white(self, a: np.ndarray) -> np.ndarray:
        return solve_triangular(self.chol, a, lower=True, check_finite=False)

    def colour(self, a: np.ndarray) -> np.ndarray:
        return self.chol @ a


def column_value(model: GyroModel, column: Column) -> float:
    """The model's current value of a linear parameter (held when it cannot be fitted)."""
    if column.effect is None:
        return float(getattr(model, column.key))
    spec = model.effect(column.effect)
    if column.effect in PHASED:
        amp, phase = PHASED[column.effect]
        angle = math.radians(spec[phase])
        return spec[amp] * (math.cos(angle) if column.key == "cos" else math.sin(angle))
    return float(spec[column.key])


@dataclass
class Fit:
    """A model refitted to the data: its linear parameters by GLS on the bin means."""

    model: GyroModel
    design: Design
    coeffs: np.ndarray          # one per design column (held columns keep the model's value)
    stderr: np.ndarray          # GLS standard errors (nan for held columns)
    held: list[Column]          # columns the data cannot determine
    chi2: float
    basis: np.ndarray           # orthonormal basis of the whitened fitted columns
    white_data: np.ndarray      # L⁻¹(y − offset)
    white_resid: np.ndarray
    resid_bins: np.ndarray      # y − prediction, deg/h, unwhitened
    pred_bins: np.ndarray

    @property
    def n_fitted(self) -> int:
        return self.basis.shape[1]


def gls_fit(builder: DesignBuilder, whitener: Whitener, y_bins: np.ndarray, model: GyroModel,
            design: Design | None = None) -> Fit:
    """Refit every linear parameter of ``model`` (base and effect amplitudes) jointly."""
    design = design or builder.design(model)
    wx = whitener.white(design.x_bins)
    norms = np.linalg.norm(wx, axis=0)
    # columns differ by 10 orders of magnitude (bias vs k3·ω³): judge rank on unit columns
    unit = wx / np.where(norms > 0, norms, 1.0)
    _, r_piv, piv = qr(unit, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r_piv))
    rank = int(np.sum(diag > 1e-9))
    keep = np.zeros(len(design.columns), dtype=bool)
    keep[piv[:rank]] = True
    keep &= norms > 0
    held = [c for c, k in zip(design.columns, keep, strict=True) if not k]
    held_values = np.array([column_value(model, c) for c in held])
    offset = design.offset_bins + (design.x_bins[:, ~keep] @ held_values if held else 0.0)
    wy = whitener.white(y_bins - offset)
    scale = norms[keep]
    q, r = np.linalg.qr(wx[:, keep] / scale)
    beta = solve_triangular(r, q.T @ wy) / scale
    r_inv = solve_triangular(r, np.eye(r.shape[0]))
    cov = (r_inv @ r_inv.T) / np.outer(scale, scale)
    coeffs = np.empty(len(design.columns))
    coeffs[keep] = beta
    coeffs[~keep] = held_values
    stderr = np.full(len(design.columns), np.nan)
    stderr[keep] = np.sqrt(np.diag(cov))
    white_resid = wy - q @ (q.T @ wy)
    pred = offset + design.x_bins[:, keep] @ beta
    fitted = apply_coefficients(model, design.columns, coeffs)
    return Fit(fitted, design, coeffs, stderr, held, float(white_resid @ white_resid), q,
               wy, white_resid, y_bins - pred, pred)


def score_from_delta(delta_chi2: float, dof: int) -> float:
    """−log10 of the χ²(dof) tail probability: one scale for effects of different size."""
    if not delta_chi2 > 0:
        return 0.0
    log_sf = float(stats.chi2.logsf(delta_chi2, dof))
    if not math.isfinite(log_sf):
        # far tail: log P(χ²_k > x) ≈ −x/2 + (k/2 − 1)·ln(x/2) − lnΓ(k/2), so huge gains stay ordered
        half = 0.5 * delta_chi2
        log_sf = -half + (0.5 * dof - 1.0) * math.log(half) - math.lgamma(0.5 * dof)
    return -log_sf / _LN10


@dataclass
class CandidateScore:
    """One effect at one shape: its likelihood gain and what the null simulations need."""

    effect: str
    shape: dict[str, float]
    delta_chi2: float
    dof: int
    structural: bool
    basis: np.ndarray                     # additive: ⊥ the base; structural: the whole design
    offset_gap: np.ndarray | None = None  # structural: P⊥_c L⁻¹(prediction_F − offset_c)
    fit: Fit | None = None                # structural: the refit with the effect
    columns: list[Column] = field(default_factory=list)
    coeffs: np.ndarray | None = None      # additive: fitted amplitudes of the extra columns
    white_contribution: np.ndarray | None = None  # the fitted part of the data it explains
    contribution_bins: np.ndarray | None = None   # its fitted signature, deg/h

    @property
    def score(self) -> float:
        return score_from_delta(self.delta_chi2, self.dof)

    def spec(self, base_model: GyroModel) -> EffectSpec:
        """The effect with its shape and fitted amplitudes (in the catalogue's keys)."""
        if self.fit is not None:
            spec = self.fit.model.effect(self.effect)
            return EffectSpec(spec.name, dict(spec.params))
        model = apply_coefficients(base_model.with_effect(placeholder_spec(self.effect, self.shape)),
                                   self.columns, self.coeffs)
        spec = model.effect(self.effect)
        return EffectSpec(spec.name, dict(spec.params))


def additive_score(name: str, shape: dict[str, float], columns: list[Column], x_bins: np.ndarray,
                   base: Fit, whitener: Whitener) -> CandidateScore:
    """Gain of adding columns to the refitted base (Frisch–Waugh: project, then regress)."""
    wc = whitener.white(x_bins)
    norms = np.linalg.norm(wc, axis=0)
    if not np.all(norms > 0):
        return CandidateScore(name, shape, 0.0, len(columns), False, np.zeros((len(base.white_resid), 0)),
                              columns=columns, coeffs=np.zeros(len(columns)))
    wc = wc / norms
    perp = wc - base.basis @ (base.basis.T @ wc)
    q, r = np.linalg.qr(perp)
    good = np.abs(np.diag(r)) > 1e-7
    if not np.all(good):
        return CandidateScore(name, shape, 0.0, len(columns), False, np.zeros((len(base.white_resid), 0)),
                              columns=columns, coeffs=np.zeros(len(columns)))
    proj = q.T @ base.white_resid
    coeffs = solve_triangular(r, proj) / norms
    white_contribution = q @ proj
    return CandidateScore(name, shape, float(proj @ proj), len(columns), False, q,
                          columns=columns, coeffs=coeffs, white_contribution=white_contribution,
                          contribution_bins=x_bins @ coeffs)


def structural_score(name: str, shape: dict[str, float], builder: DesignBuilder, base: Fit,
                     whitener: Whitener, y_bins: np.ndarray) -> CandidateScore:
    """Gain of an effect that changes every term (thermal lag, dead zone): a whole refit."""
    model = base.model.with_effect(placeholder_spec(name, shape))
    fit = gls_fit(builder, whitener, y_bins, model)
    u = whitener.white(base.pred_bins - fit.design.offset_bins)
    offset_gap = u - fit.basis @ (fit.basis.T @ u)
    delta = base.chi2 - fit.chi2
    contribution = fit.pred_bins - base.pred_bins
    return CandidateScore(name, shape, float(delta), 1, True, fit.basis, offset_gap=offset_gap,
                          fit=fit, white_contribution=base.white_resid - fit.white_resid,
                          contribution_bins=contribution)


def score_candidate(name: str, shape: dict[str, float], builder: DesignBuilder, base: Fit,
                    whitener: Whitener, y_bins: np.ndarray) -> CandidateScore:
    if name in STRUCTURAL:
        return structural_score(name, shape, builder, base, whitener, y_bins)
    columns, x = builder.extra_columns(base.model, placeholder_spec(name, shape))
    return additive_score(name, shape, columns, x, base, whitener)


@dataclass
class EffectScores:
    """Every shape tried for one effect; the best one speaks for the effect."""

    effect: str
    candidates: list[CandidateScore]

    @property
    def best(self) -> CandidateScore:
        return max(self.candidates, key=lambda c: c.delta_chi2)

    @property
    def delta_chi2(self) -> float:
        return self.best.delta_chi2

    @property
    def score(self) -> float:
        return self.best.score


def score_library(builder: DesignBuilder, base: Fit, whitener: Whitener, y_bins: np.ndarray,
                  space: SearchSpace) -> dict[str, EffectScores]:
    """Score every catalogue effect the bin-level search covers and the model lacks."""
    out: dict[str, EffectScores] = {}
    for name in searched_effects(base.model, builder.inputs):
        grid = shape_grid(name, space)
        if not grid:
            continue
        out[name] = EffectScores(
            name, [score_candidate(name, shape, builder, base, whitener, y_bins) for shape in grid])
    return out


def refine_shape(score: EffectScores, builder: DesignBuilder, base: Fit, whitener: Whitener,
                 y_bins: np.ndarray, space: SearchSpace, iterations: int = 12) -> CandidateScore:
    """Bounded scalar search in log τ between the best grid point's neighbours.

    A dead-zone threshold is profiled instead over every distinct threshold the
    slew samples inside its bracket allow (the likelihood is a step function of
    it, so a scalar search would stall on a flat step).
    """
    best = score.best
    if "threshold_dps" in best.shape:
        # two stages: the bracket thinned, then every threshold around the best of those
        tried = list(score.candidates)
        for stage in (dead_zone_candidates, "neighbourhood"):
            centre = max(tried, key=lambda s: s.delta_chi2).shape["threshold_dps"]
            values = (dead_zone_candidates(centre, space) if stage is dead_zone_candidates else
                      dead_zone_neighbourhood(centre, [c.shape["threshold_dps"] for c in tried], space))
            tried += [score_candidate(score.effect, {**best.shape, "threshold_dps": t}, builder, base,
                                      whitener, y_bins) for t in values]
        return max(tried, key=lambda s: s.delta_chi2)
    keys = [k for k in best.shape if k.endswith("tau_s")]
    if not keys:
        return best
    key = keys[0]
    values = sorted(c.shape[key] for c in score.candidates)
    i = values.index(best.shape[key])
    lo = math.log(values[max(i - 1, 0)])
    hi = math.log(values[min(i + 1, len(values) - 1)])
    cache: dict[float, CandidateScore] = {math.log(best.shape[key]): best}

    def evaluate(x: float) -> CandidateScore:
        if x not in cache:
            shape = dict(best.shape)
            shape[key] = math.exp(x)
            cache[x] = score_candidate(score.effect, shape, builder, base, whitener, y_bins)
        return cache[x]

    if hi > lo:
        # bounded Brent (scipy) on −Δχ²; every evaluation is cached and the best one seen
        # wins, so the grid point itself is never lost to a worse refinement
        optimize.minimize_scalar(lambda x: -evaluate(float(x)).delta_chi2, bounds=(lo, hi),
                                 method="bounded", options={"maxiter": iterations, "xatol": 1e-3})
    return max(cache.values(), key=lambda s: s.delta_chi2)


def null_delta_chi2(candidate: CandidateScore, base: Fit, z: np.ndarray) -> np.ndarray:
    """The candidate's gain on each simulated effect-free dataset (columns of z, whitened noise)."""
    gain = np.sum((candidate.basis.T @ z) ** 2, axis=0)
    if not candidate.structural:
        return gain
    base_gain = np.sum((base.basis.T @ z) ** 2, axis=0)
    gap = candidate.offset_gap
    return gain - base_gain - float(gap @ gap) - 2.0 * (gap @ z)


def null_scores(scores: dict[str, EffectScores], base: Fit, z: np.ndarray) -> dict[str, np.ndarray]:
    """Each effect's score (best over its shapes) on each simulated dataset."""
    out = {}
    for name, effect in scores.items():
        gains = np.max([null_delta_chi2(c, base, z) for c in effect.candidates], axis=0)
        dof = effect.candidates[0].dof
        with np.errstate(divide="ignore"):
            log_sf = stats.chi2.logsf(np.maximum(gains, 0.0), dof)
        scores = np.where(gains > 0, -log_sf / _LN10, 0.0)
        far = ~np.isfinite(scores)
        if far.any():
            scores[far] = [score_from_delta(float(g), dof) for g in gains[far]]
        out[name] = scores
    return out


def order_statistic_quantile(values: np.ndarray, level: float) -> float:
    """The ⌈level·(K+1)⌉-th smallest of K values: P(new null ≤ it) ≥ level exactly."""
    ordered = np.sort(np.asarray(values, dtype=float))
    k = min(len(ordered), math.ceil(level * (len(ordered) + 1)))
    return float(ordered[k - 1])
