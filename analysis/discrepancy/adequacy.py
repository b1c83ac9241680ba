"""Whether the named effects are the whole account: structure they leave behind, family-wise.

A catalogue effect with its own free parameters can absorb most of a shape
outside the catalogue (a bias in log(1 + t/600 s) is 90 % a linear ramp; a
decaying bias step meets a dT/dt bias where it crosses a ramp) and then be
stated at 0.99 although the data hold more. After the last refit the
out-of-catalogue probes (probes.py: smooth shapes in time, steps and
decaying steps, terms in temperature, rate sign and dT/dt) are scored once
more on the residual, each beyond the refitted base *and* the named effects,
so what they find is structure the named effects leave behind, not an
alternative that fits as well (a cubic in time fitted beside a real bias_ramp
gains only its noise).

The statistic is the best probe score, and its threshold is the (1 − α) point
of the best probe score *over the whole family* on the same simulated
effect-free residuals (``family_threshold``): each probe's own threshold is
its single (1 − α) point, and with a dozen probes "any probe significant"
fires on far more than α of effect-free records (2 of 10 controls on one
profile). The maximum is taken draw by draw, so the probes' correlations are
accounted for exactly.

When the statistic is above its threshold the result is ``unexplained`` with
the probe in ``where``, and every named effect the probe takes the place of
(the effect adds nothing significant once the probe is fitted beside the
rest) has its probability multiplied by the probability that it is the whole
account, ``1 − real_probability(statistic, threshold)``: the same odds rule
as every claim, so a claim can no longer be stated above 0.5. A named effect
that still adds significantly beside the probe keeps its probability: it is
real, and something else is there too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.probes import Probe, gain_given
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit, order_statistic_quantile, score_from_delta
from gyrocal.analysis.discrepancy.signatures import effect_columns

#: Named effects whose adequacy is judged here: the deterministic catalogue effects. A Markov
#: bias is judged by its own stationarity test before it is named (arbitration.py), a spectral
#: line is sharper than any probe, quantization is read off the output lattice.
NOT_JUDGED = ("markov_bias", "periodic_interference", "quantization")


@dataclass(frozen=True)
class Adequacy:
    """The family-wise residual-structure test after the last refit."""

    statistic: float          # best probe score (−log10 p of its χ²)
    threshold: float          # (1 − α) point of the family maximum on effect-free draws
    probe: Probe | None       # the probe with the best score

    @property
    def inadequate(self) -> bool:
        return self.probe is not None and self.statistic > self.threshold

    @property
    def whole_account(self) -> float:
        """Probability that the named effects leave nothing: the claim odds rule turned round."""
        return 1.0 - real_probability(self.statistic, self.threshold) if self.inadequate else 1.0


def family_threshold(probes: list[Probe], alpha: float) -> float:
    """The (1 − α) point of the best probe score per effect-free draw, over every probe."""
    nulls = [p.null for p in probes if p.null.size]
    if not nulls:
        return float("inf")
    return order_statistic_quantile(np.max(np.vstack(nulls), axis=0), 1.0 - alpha)


def adequacy(probes: list[Probe], alpha: float) -> Adequacy:
    """The family-wise test on probes scored against the final fit with one set of null draws."""
    if not probes:
        return Adequacy(0.0, float("inf"), None)
    best = max(probes, key=lambda p: p.score)
    return Adequacy(best.score, family_threshold(probes, alpha), best)


def judged(ctx: Context, after: Fit, found: list[FoundEffect], test: Adequacy) -> list[FoundEffect]:
    """The named effects with the probabilities the adequacy test leaves them (see module doc)."""
    if not test.inadequate or test.probe is None:
        return found
    return [replace(f, probability=f.probability * test.whole_account)
            if f.name not in NOT_JUDGED and not survives(ctx, after, f, test.probe) else f
            for f in found]


def survives(ctx: Context, after: Fit, effect: FoundEffect, probe: Probe) -> bool:
    """Whether ``effect`` still adds significantly (its own threshold) once ``probe`` is fitted.

    χ² without the effect and χ² with it, each with the probe fitted beside the
    rest (``gain_given``); their difference is the effect's gain beyond the probe,
    on as many degrees of freedom as the effect has amplitudes (one for a
    structural effect such as thermal_lag).
    """
    without = ctx.fit(after.model.without_effect(effect.name))
    chi2_without = without.chi2 - gain_given(probe, without.basis, without.white_resid)
    chi2_with = after.chi2 - gain_given(probe, after.basis, after.white_resid)
    dof = max(len(effect_columns(effect.name)), 1)
    return score_from_delta(chi2_without - chi2_with, dof) > effect.threshold
