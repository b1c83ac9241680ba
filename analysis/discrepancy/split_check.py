"""Whether each named effect keeps one size across parts of the record: a wrong name does not.

A catalogue effect fitted to structure outside the catalogue takes whatever of
that structure its shape can hold, and the adequacy probes (adequacy.py) only
look for what it leaves in *their* shapes. A real effect has one amplitude over
the whole record; a wrong name fitted to foreign structure needs a different one
where the foreign structure differs from the effect's shape. So, after the last
refit, each named deterministic effect's own binned signature (the effect at its
fitted parameters, the model with it minus the model without it) is split four
ways into parts, and each part but one is offered as a column of its own beside
the whole fit (an amplitude of its own in that part):

* **time**: halves and quarters of the record (a law that drifts, steps or
  switches);
* **temperature**: the bins above and below the median, and the four quartiles
  (a temperature law of the wrong order, a step at a temperature threshold);
* **rate sign**: positive and negative table rates (a rate-sign-dependent term
  named after an even or odd catalogue law);
* **|rate|**: three bands of the moving bins (a rate law of the wrong power).

The score of each split is −log10 p of its Δχ² on its degrees of freedom, after
the whole refitted basis; the statistic is the best score, its threshold the
(1 − ``ALPHA_SPLIT``) point of the best score over every (effect, split) pair on the same simulated
effect-free residuals the adequacy test uses, draw by draw, so the
comparisons' correlations are accounted for exactly. A split whose column is
almost the effect itself (the effect lives on one side only) cannot tell
anything and is left out (``MIN_FREE_FRACTION``).

When it fires, the result is ``unexplained`` with the effect and the split in
``where``, and the effect's probability is multiplied by
``1 − real_probability(statistic, threshold)`` (the claim odds rule turned round,
as adequacy.py does), so it can no longer be stated above 0.5.

Why: the published held-out tables showed catalogue names at ≥ 0.8 on foreign
structure (a scale-factor step above a temperature threshold, a bias in
ΔT·dT/dt). On our own cases (benchmarks/validate_split_check.py, 90 runs at
10σ) such names kept 1.0 beside an adequacy probe that had fired, because the
wrong law still added significantly beside the probe (adequacy.survives): a
dT/dt law growing with temperature as temp_rate_bias 0.94–1.0 (5 runs), a
scale-factor step above 36 °C as sf_temp_quadratic 1.0. With the check, wrong
claims ≥ 0.8 went 20 → 12 of 90; 10σ catalogue effects named first 70 → 70 of
72, the check firing on none of them; 0 of 600 draws under the right name.
Cost 0.03 s CPU per run on a P2-sized record (docs/discrepancy-validation.md,
"Named effects split across the record").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit, order_statistic_quantile

#: Family-wise false-alarm rate of this test on effect-free residuals (issue 29: a new test
#: adds ≤ 0.5 % to the controls' false `unexplained`).
ALPHA_SPLIT = 0.005
#: Named effects this test does not judge: a Markov bias has no deterministic signature, a
#: spectral line's bin means average out, quantization is read off the output lattice.
NOT_SPLIT = ("markov_bias", "periodic_interference", "quantization")
#: A split column must keep this fraction of the effect's whitened norm once the whole fit is
#: projected out (less: the effect lives on one side only and the split is the effect itself).
MIN_FREE_FRACTION = 0.02
#: Bins each part of a split must hold (fewer: no amplitude of its own to compare).
MIN_PART_BINS = 20
_LN10 = float(np.log(10.0))


@dataclass(frozen=True)
class SplitCheck:
    """The split test's outcome: best score, its family-wise threshold, which effect and split."""

    statistic: float          # −log10 p of the best split's Δχ² on its degrees of freedom
    threshold: float          # (1 − ALPHA_SPLIT) point of the best score on effect-free draws
    effect: str | None
    split: str | None

    @property
    def fires(self) -> bool:
        return self.effect is not None and self.statistic > self.threshold

    def describe(self) -> str:
        return (f"{self.effect} does not keep one size across {self.split} (score {self.statistic:.1f}, "
                f"family-wise threshold {self.threshold:.1f}): a catalogue law fitted to structure "
                "outside the catalogue")


def _parts(values: np.ndarray, n_parts: int) -> np.ndarray:
    """Part index per bin: ``n_parts`` groups of equal count by ``values``."""
    ranks = np.argsort(np.argsort(values, kind="stable"), kind="stable")
    return (ranks * n_parts) // values.size


def _splits(ctx: Context) -> dict[str, np.ndarray]:
    """The splits: a part index per bin (−1: the bin takes part in no comparison)."""
    bins = ctx.bins
    temp = bins.mean(ctx.inputs.chamber_temp_c)
    rate = ctx.rate_bins_dps
    moving = np.abs(rate) > 0.05
    splits = {"the two halves of the record in time": _parts(bins.centre_s, 2),
              "the four quarters of the record in time": _parts(bins.centre_s, 4),
              "positive and negative table rates": np.where(moving, (rate > 0).astype(int), -1)}
    if np.ptp(temp) > 2.0:
        splits["temperatures above and below the record's median"] = _parts(temp, 2)
        splits["the record's four temperature quartiles"] = _parts(temp, 4)
    if moving.sum() >= 3 * MIN_PART_BINS:
        speed = np.full(rate.size, -1)
        speed[moving] = _parts(np.abs(rate[moving]), 3)
        splits["three bands of |rate| among the moving bins"] = speed
    return {name: part for name, part in splits.items()
            if all(np.sum(part == k) >= MIN_PART_BINS for k in range(part.max() + 1))}


def _columns(ctx: Context, after: Fit, found: list[FoundEffect]
             ) -> list[tuple[np.ndarray, str, str]]:
    """Per (effect, split): an orthonormal basis of the split parts beyond the whole fit."""
    splits = _splits(ctx)
    whole = ctx.builder.binned_rate_dph(after.model)
    out = []
    for f in found:
        if f.name in NOT_SPLIT or not after.model.has_effect(f.name):
            continue
        signature = whole - ctx.builder.binned_rate_dph(after.model.without_effect(f.name))
        norm2 = float(np.sum(ctx.whitener.white(signature) ** 2))
        if not norm2 > 0:
            continue
        for split, part in splits.items():
            # one column per part but the last (the whole signature is in the fit already)
            x = np.column_stack([np.where(part == k, signature, 0.0) for k in range(part.max())])
            w = ctx.whitener.white(x)
            w = w - after.basis @ (after.basis.T @ w)
            keep = np.sum(w * w, axis=0) > MIN_FREE_FRACTION * norm2
            if keep.any():
                q, r = np.linalg.qr(w[:, keep])
                out.append((q[:, np.abs(np.diag(r)) > 1e-9 * np.sqrt(norm2)], f.name, split))
    return out


def _score(gain: np.ndarray, dof: int) -> np.ndarray:
    return -stats.chi2.logsf(gain, dof) / _LN10


def split_check(ctx: Context, after: Fit, found: list[FoundEffect]) -> SplitCheck:
    """Best split score of the named effects against its family-wise effect-free threshold."""
    return judge(split_columns(ctx, after, found), after, ctx.rng, ctx.n_null)


def split_columns(ctx: Context, after: Fit, found: list[FoundEffect]) -> list[tuple[np.ndarray, str, str]]:
    """The (basis, effect, split) triples the test scores; they depend on the design, not the data."""
    return [c for c in _columns(ctx, after, found) if c[0].shape[1]]


def judge(columns: list[tuple[np.ndarray, str, str]], after: Fit, rng: np.random.Generator,
          n_null: int) -> SplitCheck:
    """The best score on ``after``'s residual and its threshold from ``n_null`` effect-free draws."""
    if not columns:
        return SplitCheck(0.0, float("inf"), None, None)
    z = rng.standard_normal((after.white_resid.size, n_null))
    null_resid = z - after.basis @ (after.basis.T @ z)
    scores = [float(_score(np.sum((q.T @ after.white_resid) ** 2), q.shape[1])) for q, _, _ in columns]
    null_best = np.max([_score(np.sum((q.T @ null_resid) ** 2, axis=0), q.shape[1]) for q, _, _ in columns],
                       axis=0)
    best = int(np.argmax(scores))
    return SplitCheck(scores[best], order_statistic_quantile(null_best, 1.0 - ALPHA_SPLIT),
                      columns[best][1], columns[best][2])


def judged_by_split(found: list[FoundEffect], check: SplitCheck) -> list[FoundEffect]:
    """The named effects with the split effect's probability taken below 0.5 when the test fires.

    The claim odds rule turned round, as adequacy.py does: the probability that the
    effect's one size is the whole account is 1 − real_probability(score, threshold).
    """
    if not check.fires:
        return found
    keep = 1.0 - real_probability(check.statistic, check.threshold)
    return [replace(f, probability=f.probability * keep) if f.name == check.effect else f for f in found]
