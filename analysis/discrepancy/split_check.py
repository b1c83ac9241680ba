"""Whether each named effect keeps its size across halves of the record: a wrong name does not.

A catalogue effect fitted to structure outside the catalogue takes whatever of
that structure its shape can hold, and the adequacy probes (adequacy.py) only
look for what it leaves in *their* shapes. A real effect has one amplitude over
the whole record; a wrong name fitted to foreign structure needs a different one
where the foreign structure differs from the effect's shape. So, after the last
refit, each named deterministic effect's own binned signature (the effect at its
fitted parameters, the model with it minus the model without it) is split four
ways and the split part is offered as one more column beside the whole fit:

* the **second half of the record in time** (a law that drifts, steps or
  switches);
* the bins **above the record's median temperature** (a temperature law of the
  wrong order, a step at a temperature threshold);
* the bins at **positive table rate** (a rate-sign-dependent term named after an
  even or odd catalogue law);
* the moving bins **above the median |rate|** (a rate law of the wrong power).

The gain of each split column (Δχ², one degree of freedom, after the whole
refitted basis) is the statistic; its threshold is the (1 − ``ALPHA_SPLIT``)
point of the best gain over every (effect, split) pair on the same simulated
effect-free residuals the adequacy test uses, draw by draw, so the
comparisons' correlations are accounted for exactly. A split whose column is
almost the effect itself (the effect lives on one side only) cannot tell
anything and is left out (``MIN_FREE_FRACTION``).

When it fires, the result is ``unexplained`` with the effect and the split in
``where``, and the effect's probability is multiplied by
``1 − real_probability(statistic, threshold)`` (the claim odds rule turned round,
as adequacy.py does), so it can no longer be stated above 0.5.

Why: on our own out-of-catalogue cases (benchmarks/validate_split_check.py) a
scale-factor step above a temperature threshold, a bias in ΔT·dT/dt and a bias
∝ table acceleration were named sf_temp_quadratic, temp_hysteresis and
table_angle_harmonic at ≥ 0.8, the adequacy probes finding nothing left
(docs/discrepancy-validation.md, "Named effects split across the record").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

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
#: Bins each side of a split must hold (fewer: no amplitude of its own to compare).
MIN_SIDE_BINS = 20


@dataclass(frozen=True)
class SplitCheck:
    """The split test's outcome: best gain, its family-wise threshold, which effect and split."""

    statistic: float
    threshold: float
    effect: str | None
    split: str | None

    @property
    def fires(self) -> bool:
        return self.effect is not None and self.statistic > self.threshold

    def describe(self) -> str:
        return (f"{self.effect} does not keep one size across {self.split} (Δχ² {self.statistic:.1f}, "
                f"family-wise threshold {self.threshold:.1f}): a catalogue law fitted to structure "
                "outside the catalogue")


def _masks(ctx: Context) -> dict[str, np.ndarray]:
    """The splits: side "True" of each, per bin."""
    bins = ctx.bins
    temp = bins.mean(ctx.inputs.chamber_temp_c)
    rate = ctx.rate_bins_dps
    moving = np.abs(rate) > 0.05
    masks = {"the two halves of the record in time": bins.centre_s > np.median(bins.centre_s)}
    if np.ptp(temp) > 2.0:
        masks["temperatures above and below the record's median"] = temp > np.median(temp)
    masks["positive and negative table rates"] = rate > 0.05
    if moving.sum() >= 2 * MIN_SIDE_BINS:
        masks["|rate| above and below the median of the moving bins"] = (
            np.abs(rate) > np.median(np.abs(rate[moving])))
    return {k: m for k, m in masks.items()
            if m.sum() >= MIN_SIDE_BINS and (~m).sum() >= MIN_SIDE_BINS}


def _columns(ctx: Context, after: Fit, found: list[FoundEffect]
             ) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """The whitened split columns beyond the whole fit (unit norm), and their (effect, split)."""
    masks = _masks(ctx)
    whole = ctx.builder.binned_rate_dph(after.model)
    cols, labels = [], []
    for f in found:
        if f.name in NOT_SPLIT or not after.model.has_effect(f.name):
            continue
        signature = whole - ctx.builder.binned_rate_dph(after.model.without_effect(f.name))
        norm2 = float(np.sum(ctx.whitener.white(signature) ** 2))
        if not norm2 > 0:
            continue
        for split, mask in masks.items():
            w = ctx.whitener.white(np.where(mask, signature, 0.0))
            w = w - after.basis @ (after.basis.T @ w)
            free2 = float(w @ w)
            if free2 > MIN_FREE_FRACTION * norm2 and free2 > 0:
                cols.append(w / np.sqrt(free2))
                labels.append((f.name, split))
    return (np.column_stack(cols) if cols else np.zeros((after.white_resid.size, 0))), labels


def split_check(ctx: Context, after: Fit, found: list[FoundEffect]) -> SplitCheck:
    """Best split gain of the named effects against its family-wise effect-free threshold."""
    cols, labels = _columns(ctx, after, found)
    if not labels:
        return SplitCheck(0.0, float("inf"), None, None)
    gains = (cols.T @ after.white_resid) ** 2
    z = ctx.rng.standard_normal((after.white_resid.size, ctx.n_null))
    null_resid = z - after.basis @ (after.basis.T @ z)
    null_best = np.max((cols.T @ null_resid) ** 2, axis=0)
    best = int(np.argmax(gains))
    return SplitCheck(float(gains[best]), order_statistic_quantile(null_best, 1.0 - ALPHA_SPLIT),
                      *labels[best])


def judged_by_split(found: list[FoundEffect], check: SplitCheck) -> list[FoundEffect]:
    """The named effects with the split effect's probability taken below 0.5 when the test fires.

    Gains are Δχ² here, the claim odds rule works in −log10 p: the difference of the two
    is turned into decades by the χ²₁ tail's ln(10)/2 per unit of Δχ² (approximately).
    """
    if not check.fires:
        return found
    decades = (check.statistic - check.threshold) / (2.0 * np.log(10.0))
    keep = 1.0 - real_probability(float(decades), 0.0)
    return [replace(f, probability=f.probability * keep) if f.name == check.effect else f for f in found]
