"""The effects a search round weighs, behind one interface, and the registry of their kinds.

Every kind of effect the workflow can name is one ``EffectKind`` in ``KINDS``:

* ``propose``: score what the current model lacks on the round's fit, as
  ``Candidate`` objects (the catalogue's bin-level effects by GLS, a
  Gauss–Markov bias by the Whittle likelihood, a spectral line on the
  full-rate spectrum);
* ``own_gap``: the metric where a named effect of that kind lives (own_gap.py).

A ``Candidate`` carries its score and Δχ², its column of the simulated
effect-free maximum (``null_scores``, from which the round's threshold comes),
whether a claim near the threshold must also open a gap, and ``admit``: the
search state once it is named. Quantization is found from the output lattice
in the noise pass, never proposed; its kind only measures its gap.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field, replace

import numpy as np

from gyrocal.analysis.discrepancy.arbitration import gain_beside, outside_odds
from gyrocal.analysis.discrepancy.context import Context, markov_test, refine_found
from gyrocal.analysis.discrepancy.gap import AllanRatios, Metric, SegmentGeometry
from gyrocal.analysis.discrepancy.lookalikes import (
    LookAlike,
    lookalike_group,
    real_probability,
    separating_experiment,
)
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.own_gap import (
    EffectGap,
    NullRefit,
    Pattern,
    Residuals,
    dwell_metrics,
    markov_metrics,
    pattern_metrics,
    quantization_metrics,
)
from gyrocal.analysis.discrepancy.periodic import PeriodicScan
from gyrocal.analysis.discrepancy.probes import Probe
from gyrocal.analysis.discrepancy.quantization import PulseLattice, line_within_quantization
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import (
    EffectScores,
    Fit,
    null_scores,
    order_statistic_quantile,
    refine_shape,
    score_library,
)
from gyrocal.analysis.discrepancy.stochastic import MARKOV, StochasticCandidate
from gyrocal.models.gyro_model import EffectSpec, GyroModel

PERIODIC = "periodic_interference"
QUANTIZATION = "quantization"
DEAD_ZONE = "dead_zone"


@dataclass(frozen=True)
class SearchState:
    """What one search round hands to the next: the model so far, the noise, what was named."""

    current: GyroModel
    noise: NoiseModel
    lattice: PulseLattice | None = None
    found: tuple[FoundEffect, ...] = ()
    notes: tuple[str, ...] = ()

    def noted(self, *notes: str) -> SearchState:
        return replace(self, notes=self.notes + notes)


@dataclass(frozen=True)
class Weighing:
    """What a round weighed its candidates on: the fit, the threshold, the probes, the catalogue."""

    fit: Fit
    threshold: float
    probes: list[Probe]
    scores: dict[str, EffectScores] = field(default_factory=dict)


class Candidate(ABC):
    """One effect the current model lacks, scored on the round's fit."""

    name: str
    #: a claim less than GAP_CHECK_MARGIN above the threshold must also open a gap metric
    checks_gap = False
    #: a probe outside the catalogue may preempt it (a spectral line is sharper than any probe)
    probes_compete = True

    @property
    @abstractmethod
    def score(self) -> float: ...

    @property
    @abstractmethod
    def delta_chi2(self) -> float: ...

    @abstractmethod
    def null_scores(self, fit: Fit, z: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Its score on each simulated effect-free dataset (a column of the library maximum)."""

    @abstractmethod
    def admit(self, ctx: Context, state: SearchState, weighing: Weighing) -> SearchState:
        """The search state with this effect named."""


class CatalogueCandidate(Candidate):
    """A bin-level catalogue effect: its shapes by grid, amplitudes by GLS (scoring.py)."""

    checks_gap = True

    def __init__(self, scores: EffectScores) -> None:
        self.name, self.scores = scores.effect, scores

    @property
    def score(self) -> float:
        return self.scores.score

    @property
    def delta_chi2(self) -> float:
        return self.scores.delta_chi2

    def null_scores(self, fit: Fit, z: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return null_scores({self.name: self.scores}, fit, z)[self.name]

    def admit(self, ctx: Context, state: SearchState, weighing: Weighing) -> SearchState:
        """Refine the shape, split the probability with look-alikes and the probes, refit."""
        fit, threshold = weighing.fit, weighing.threshold
        refined = refine_shape(self.scores, ctx.builder, fit, ctx.whitener, ctx.y_bins, ctx.space)
        self.scores.candidates.append(refined)
        spec = refined.spec(fit.model)
        split, rivals = lookalike_group(self.name, weighing.scores)
        # the effect's shape parameters (τ, a threshold) were fitted too: they count as free
        # parameters in the BIC comparison with the probes, as every probe column does (a warm-up
        # with τ refitted to twice the record's third took a bias in √t at 0.92 against a cubic
        # in time charged for two columns more than the warm-up's one)
        odds, outside = outside_odds(weighing.probes, refined.dof + len(refined.shape), refined.delta_chi2,
                                     ctx.bins.n_bins, [gain_beside(fit, p, refined) for p in weighing.probes])
        real = real_probability(refined.score, threshold)
        probability = split * real / (1.0 + odds)
        rivals = [replace(r, probability=r.probability * real / (1.0 + odds)) for r in rivals]
        experiment = separating_experiment(self.name, [r.name for r in rivals], spec.params.get("tau_s"),
                                           ctx.space.rate_levels_dps)
        if outside is not None and odds * split * real / (1.0 + odds) >= 0.01:
            rivals.append(LookAlike(f"outside the catalogue: {outside.describe()}",
                                    odds * split * real / (1.0 + odds), 0.0))
        found = FoundEffect(self.name, {}, probability, rivals, experiment, refined.score,
                            refined.delta_chi2, threshold)
        return _with_deterministic(ctx, state, fit, spec, found)


class MarkovCandidate(Candidate):
    """A first-order Gauss–Markov bias over the whole record (stochastic.py); named, it joins the noise."""

    name = MARKOV

    def __init__(self, test: StochasticCandidate) -> None:
        self.test = test

    @property
    def score(self) -> float:
        return self.test.score

    @property
    def delta_chi2(self) -> float:
        return self.test.lr

    def null_scores(self, fit: Fit, z: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.test.null_scores()

    def admit(self, ctx: Context, state: SearchState, weighing: Weighing) -> SearchState:
        spec = EffectSpec(MARKOV, dict(self.test.params))
        noise = replace(state.noise, markov_sigma_dph=spec["sigma_dph"], markov_tau_s=spec["tau_s"])
        ctx.use_noise(noise)
        found = FoundEffect(MARKOV, {}, real_probability(self.score, weighing.threshold), [], "",
                            self.score, self.delta_chi2, weighing.threshold)
        state = replace(state, current=state.current.with_effect(spec), noise=noise,
                        found=state.found + (found,))
        if not self.test.at_rrw_limit:
            return state
        return state.noted(
            f"markov_bias: τ at the top of its range ({spec['tau_s']:.0f} s, longer than the "
            f"record): to this record it is a rate random walk of {self.test.rrw_deg_per_h_rth:.3g} deg/h/√h")


class PeriodicCandidate(Candidate):
    """The strongest line of the full-rate residual's spectrum (periodic.py)."""

    name = PERIODIC
    probes_compete = False

    def __init__(self, scan: PeriodicScan) -> None:
        self.scan = scan

    @property
    def score(self) -> float:
        return self.scan.score

    @property
    def delta_chi2(self) -> float:
        return self.scan.delta_chi2

    def null_scores(self, fit: Fit, z: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        # exact under the noise model: the max-of-M tail makes the periodic p-value uniform
        return -np.log10(rng.uniform(size=z.shape[1]))

    def admit(self, ctx: Context, state: SearchState, weighing: Weighing) -> SearchState:
        spec = EffectSpec(PERIODIC, {"freq_hz": self.scan.freq_hz, "amplitude_dph": self.scan.amplitude_dph})
        found = FoundEffect(PERIODIC, {}, real_probability(self.score, weighing.threshold), [], "",
                            self.score, self.delta_chi2, weighing.threshold)
        return _with_deterministic(ctx, state, weighing.fit, spec, found)


def _with_deterministic(ctx: Context, state: SearchState, fit: Fit, spec: EffectSpec,
                        found: FoundEffect) -> SearchState:
    """The state with a deterministic effect added and every found τ refitted jointly."""
    current = refine_found(ctx, fit.model.with_effect(spec), [f.name for f in state.found] + [spec.name])
    return replace(state, current=current, found=state.found + (found,))


@dataclass(frozen=True)
class GapInputs:
    """What an effect's own gap is measured on (workflow's gap pass)."""

    given: GyroModel          # the model as given
    before: Fit               # the given model refitted
    after: Fit                # the final joint refit
    null_resid: np.ndarray    # effect-free residuals through the final refit (columns, deg/h per bin)
    geometry: SegmentGeometry
    metrics: dict[str, Metric]
    allan: AllanRatios        # the whole-record Allan mismatch's ratios, before, after, effect-free


class EffectKind(ABC):
    """One kind of effect: what it proposes in a round and where its gap is measured."""

    def propose(self, ctx: Context, state: SearchState, fit: Fit) -> list[Candidate]:
        return []

    @abstractmethod
    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None: ...


class CatalogueKind(EffectKind):
    def propose(self, ctx: Context, state: SearchState, fit: Fit) -> list[Candidate]:
        # a log with sensor_temp_c has no thermal_lag to score (signatures.searched_effects)
        scores = score_library(ctx.builder, fit, ctx.whitener, ctx.y_bins, ctx.space)
        return [CatalogueCandidate(s) for s in scores.values()]

    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None:
        """Its pattern in the segments where it stands out (own_gap.pattern_metrics)."""
        return pattern_metrics(name, _pattern(ctx, name, g), Residuals(g.before.resid_bins, g.before.white_resid),
                               Residuals(g.after.resid_bins, g.after.white_resid), _null_refit(ctx, g), g.geometry,
                               _segment_names(ctx))


def _pattern(ctx: Context, name: str, g: GapInputs) -> Pattern:
    """The named effect's contribution to the final refit, with what the base refit absorbs projected out."""
    whitener, builder = ctx.whitener, ctx.builder
    full = builder.binned_rate_dph(g.after.model)
    contribution = full - builder.binned_rate_dph(g.after.model.without_effect(name))
    white = whitener.white(contribution)
    white = white - g.before.basis @ (g.before.basis.T @ white)
    return Pattern(whitener.colour(white), white)


def _null_refit(ctx: Context, g: GapInputs) -> NullRefit:
    return NullRefit(ctx.whitener.chol, g.after.basis)


def _segment_names(ctx: Context) -> list[str]:
    return [ctx.segments.names[k] for k in np.unique(ctx.segments.bin_index(ctx.bins))]


class DeadZoneKind(CatalogueKind):
    #: Dwells up to this many times the fitted threshold count as near the zone (own_gap.dwell_metrics).
    NEAR = 2.0

    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None:
        """Its pattern metrics, headed by G1 over every dwell inside or near the zone (own_gap.dwell_metrics)."""
        gap = super().own_gap(ctx, name, g)
        if gap is None or not gap.metrics:
            return gap
        near_dps = self.NEAR * g.after.model.effect(name)["threshold_dps"]
        return dwell_metrics(gap, near_dps, g.geometry.means(ctx.rate_bins_dps),
                             Residuals(g.before.resid_bins, g.before.white_resid),
                             Residuals(g.after.resid_bins, g.after.white_resid), _null_refit(ctx, g), g.geometry,
                             _pattern(ctx, name, g))


class MarkovKind(EffectKind):
    def propose(self, ctx: Context, state: SearchState, fit: Fit) -> list[Candidate]:
        return [] if state.current.has_effect(MARKOV) else [MarkovCandidate(markov_test(ctx, fit))]

    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None:
        """The Allan mismatch over the τ the process owns (own_gap.markov_metrics)."""
        return markov_metrics(name, g.after.model.effect(name)["tau_s"], g.allan)


class PeriodicKind(EffectKind):
    def propose(self, ctx: Context, state: SearchState, fit: Fit) -> list[Candidate]:
        if state.current.has_effect(PERIODIC):
            return []
        scan = ctx.scan(fit)
        if scan is None or (state.lattice is not None and line_within_quantization(
                scan.amplitude_dph, scan.freq_hz, state.lattice.pulse_arcsec)):
            return []   # none, or the quantization's beat, bounded in angle: not interference
        return [PeriodicCandidate(scan)]

    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None:
        return EffectGap(name, {}, "spectrum_peak") if "spectrum_peak" in g.metrics else None


class QuantizationKind(EffectKind):
    def own_gap(self, ctx: Context, name: str, g: GapInputs) -> EffectGap | None:
        return quantization_metrics(ctx.resid_full(g.after), ctx.builder.rate_dph(g.after.model), ctx.fs_hz,
                                    NoiseModel.of_model(g.given), g.after.model.effect(name)["pulse_arcsec"],
                                    ctx.rng)


#: The kinds a search round proposes from, in the order their candidates are ranked (the first of
#: equal scores wins) and their random draws are taken.
KINDS: tuple[EffectKind, ...] = (CatalogueKind(), MarkovKind(), PeriodicKind())
_BY_NAME: dict[str, EffectKind] = {MARKOV: KINDS[1], PERIODIC: KINDS[2], QUANTIZATION: QuantizationKind(),
                                   DEAD_ZONE: DeadZoneKind()}


def kind_of(name: str) -> EffectKind:
    """The kind a named effect belongs to (the catalogue's bin-level effects by default)."""
    return _BY_NAME.get(name, KINDS[0])


def library_threshold(candidates: list[Candidate], fit: Fit, z: np.ndarray, rng: np.random.Generator,
                      alpha: float) -> float:
    """The (1 − α) point of the simulated effect-free maximum over every candidate's score."""
    columns = [c.null_scores(fit, z, rng) for c in candidates]
    library_max = np.max(np.vstack(columns), axis=0) if columns else np.zeros(z.shape[1])
    return order_statistic_quantile(library_max, 1.0 - alpha)
