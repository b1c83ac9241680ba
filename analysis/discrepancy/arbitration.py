"""The rules that arbitrate between candidates before anything is named.

* A Gauss–Markov bias against deterministic slow structure: a process with a
  long τ imitates almost any slow curve over one record, and a slow shape
  catches part of any Markov realisation; each reading must leave nothing of
  the other behind (``explained_by_markov``, ``markov_survives``,
  ``structure_behind_markov``), and the process must be stationary over the
  record (``unless_nonstationary``).
* A probe outside the catalogue against the best candidate
  (``preempting_probe``): the probe wins when it is the better account of the
  data; ``outside_odds`` lets the probes share a named effect's probability.
* The gap check (``gap_open``): a deterministic claim near the threshold must
  also close a gap that stands out of the noise.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from gyrocal.analysis.discrepancy.context import Context, markov_test, markov_test_of
from gyrocal.analysis.discrepancy.gap import SegmentGeometry, allan_mismatch, g1
from gyrocal.analysis.discrepancy.probes import (
    POSITIONS,
    Probe,
    ProbeInputs,
    ProbeKind,
    gain_given,
    significant_by_strength,
)
from gyrocal.analysis.discrepancy.process_shape import gauss_markov_shape
from gyrocal.analysis.discrepancy.result import ALPHA
from gyrocal.analysis.discrepancy.scoring import (
    CandidateScore,
    EffectScores,
    Fit,
    Whitener,
    gls_fit,
    order_statistic_quantile,
    refine_shape,
    score_candidate,
    score_from_delta,
)
from gyrocal.analysis.discrepancy.signatures import apply_coefficients
from gyrocal.analysis.discrepancy.stochastic import (
    MARKOV,
    Stationarity,
    StochasticCandidate,
    fine_bins,
    stationarity_test,
)
from gyrocal.models.gyro_model import EffectSpec, GyroModel

#: A deterministic effect is named only while G1 or the Allan mismatch of the residual is
#: above this quantile of its effect-free distribution (``_gap_open``), judged on this many draws.
GAP_OPEN_LEVEL = 0.9
#: ... asked only of claims less than this many decades above the threshold (probability
#: < 0.91): a matched filter is far more sensitive than G1 or the Allan curve, and asking it
#: of every claim lost 6σ effects scoring 9 to 12 against a threshold of 2.9 (6 of 12 runs).
GAP_CHECK_MARGIN = 1.0
GAP_NULL_DRAWS = 200
GAP_ALLAN_DRAWS = 40


def gap_open(ctx: Context, fit: Fit, z: np.ndarray) -> bool:
    """Whether the residual still shows a gap: G1 or the Allan mismatch above GAP_OPEN_LEVEL.

    The second condition for naming a deterministic effect (its score above the
    threshold is the first): a claim must also close a gap that stands out of
    the noise, or it only fits noise (an effect-free control once drew a cubic
    term at 0.99 with every gap metric at its floor). Both metrics are judged
    against the same simulated effect-free residuals as the threshold.
    """
    bins = ctx.bins
    geometry = SegmentGeometry.of(ctx.segments.bin_index(bins), ctx.whitener.covariance)
    draws = z[:, :GAP_NULL_DRAWS]
    null_resid = ctx.whitener.colour(draws - fit.basis @ (fit.basis.T @ draws))
    if g1(geometry, fit.resid_bins) > order_statistic_quantile(g1(geometry, null_resid), GAP_OPEN_LEVEL):
        return True
    null_allan = [allan_mismatch(null_resid[:, k], bins, ctx.noise) for k in range(GAP_ALLAN_DRAWS)]
    return allan_mismatch(fit.resid_bins, bins, ctx.noise) > order_statistic_quantile(
        np.array(null_allan), GAP_OPEN_LEVEL)


def explained_by_markov(ctx: Context, model: GyroModel, markov: StochasticCandidate,
                         rival: EffectScores, threshold: float) -> bool:
    """Whether a slow structure that outscored the Markov bias is only that bias's wander.

    Scored under a noise model without the Markov process, any slow deterministic
    shape catches part of a Markov realisation and can outscore it. Rescored under the noise model *with* the fitted process, a
    real effect keeps its significance and a mere look-alike falls below the
    threshold: then the Markov bias is the better explanation. Asked only when the
    Markov bias's own likelihood gain is at least the rival's: a Markov process
    fitted to a real 20σ bias ramp also "explains" it, but with far less
    likelihood (LR 250 against Δχ² 380). Not asked when the
    fitted process is slower than the record (``at_rrw_limit``): a walk that slow
    is any slow drift, and a named deterministic shape is the sharper claim (a
    20σ bias_ramp was otherwise taken for a random walk).
    """
    noise = replace(ctx.noise, markov_sigma_dph=markov.params["sigma_dph"],
                    markov_tau_s=markov.params["tau_s"])
    bins = ctx.bins
    whitener = Whitener(noise.bin_covariance(bins.centre_s, bins.width_s, bins.samples_per_bin,
                                             ctx.fs_hz))
    fit = gls_fit(ctx.builder, whitener, ctx.y_bins, model)
    candidate = score_candidate(rival.effect, rival.best.shape, ctx.builder, fit, whitener,
                                ctx.y_bins)
    return candidate.score <= threshold


def step_time_at_full_rate(probe: Probe, resid_dph: np.ndarray, full: ProbeInputs) -> float:
    """The step time to one sample, searched within a grid spacing of the probe's.

    The probe's positions are 150 points of the bin grid; a 300 ppm scale-factor step
    placed 20 s off leaves 200 deg/h for 20 s of a 200 deg/s dwell, which the
    one-second Markov test reads as a process (LR 650 000). With the step size held,
    the squared-error change of a step starting at sample k is a reverse cumulative sum.
    """
    t = full.t_s
    half_window_s = (t[-1] - t[0]) / POSITIONS
    lo, hi = np.searchsorted(t, [probe.where - half_window_s, probe.where + half_window_s])
    lo, hi = max(int(lo), 1), min(int(hi), len(t) - 1)
    if hi <= lo:
        return probe.where
    # the step held at its size from sample lo on: its value at each sample (deg/h)
    unit = (np.full(len(t) - lo, probe.size) if probe.kind is ProbeKind.BIAS_STEP
            else probe.size * 1e-6 * 3600.0 * full.rate_dps[lo:])
    change = unit * unit - 2.0 * unit * resid_dph[lo:]            # SSE change from each sample on
    tail = np.cumsum(change[::-1])[::-1]                          # step starting at lo + k
    return float(t[lo + int(np.argmin(tail[: hi - lo]))])


def probe_explains_markov(ctx: Context, fit: Fit, probe: Probe) -> bool:
    """Whether the Markov bias is gone once the probe's shape is refitted with the base.

    The separation of a stationary random process from deterministic slow structure:
    a Gauss–Markov process with a long τ imitates almost any slow curve over one
    record (a bias accelerating with time, a ramp in |t − t0| were named markov_bias
    at 1.0). A real step, curve or sinusoid leaves white noise behind once fitted
    with its few columns; a Markov process leaves its other frequencies. So the
    probe preempts the Markov bias if the Markov test on the residual of the joint
    refit is no longer significant (`markov_left`), by the same α as every claim.
    A probe merely significant under the noise with the fitted process is no
    evidence against it: a slow sinusoid catches two wiggles of a τ = 1000 s
    process on a 1-hour record at the 2 % tail.
    """
    whitener = ctx.whitener
    full = ctx.probe_inputs()
    if probe.kind in (ProbeKind.BIAS_STEP, ProbeKind.SF_STEP):
        probe = replace(probe, where=step_time_at_full_rate(probe, ctx.resid_full(fit), full))
    c_white = whitener.white(probe.signal_dph(ctx.probe_bins))
    kept = [k for k, c in enumerate(fit.design.columns) if not any(c is h for h in fit.held)]
    x_white = whitener.white(fit.design.x_bins[:, kept])
    # Frisch–Waugh: the probe's size is its joint coefficient; the base moves by −(X'X)⁻¹X'c
    shift = np.linalg.lstsq(x_white, c_white, rcond=None)[0]
    coeffs = fit.coeffs.copy()
    coeffs[kept] -= shift
    model = apply_coefficients(fit.model, fit.design.columns, coeffs)
    resid = ctx.y_full - ctx.builder.rate_dph(model) - probe.signal_dph(full)
    return not markov_left(markov_test_of(ctx, resid))


def probe_beats_effect(fit: Fit, probe: Probe, effect: EffectScores, threshold: float) -> bool:
    """Whether a probe is the better account of the data than a catalogue effect.

    The effect must add nothing significant (the library threshold every claim must
    pass) once the probe is fitted; and either the probe still adds significantly
    (its own calibrated threshold) once the effect is fitted, or, alone, it explains
    more than the effect after its search and extra-column penalties
    (``Probe.penalised_against``; the second form for a structural effect, which is
    not nested with the probe: a thermal lag imitates a scale-factor step well
    enough that the step adds little beyond it, yet explains 68 of its 108) by more
    than the effect itself lets a probe do by chance (``excess_if_effect_true``).
    A probe that only nests the effect (the cubic in time nests bias_ramp) adds
    nothing beyond a real one; an effect that only approximates the probe (ω² and
    ω³ for a rate² on one sign) adds nothing beyond it.
    """
    best = effect.best
    probe_given_effect = gain_beside(fit, probe, best)
    effect_given_probe = best.delta_chi2 + probe_given_effect - probe.delta_chi2
    if score_from_delta(effect_given_probe, best.dof) > threshold:
        return False
    if score_from_delta(probe_given_effect, probe.dof) > probe.threshold:
        return True
    excess = probe.penalised_against(best.dof, len(fit.white_resid)) - best.delta_chi2
    return excess > max(0.0, excess_if_effect_true(fit, probe, best))


def gain_beside(fit: Fit, probe: Probe, best: CandidateScore) -> float:
    """Δχ² of the probe fitted beside the effect (with a structural effect, beside its refit)."""
    if best.structural:
        return gain_given(probe, best.fit.basis, best.fit.white_resid)
    if best.white_contribution is None:     # an effect with no signature here: nothing beside it
        return gain_given(probe, fit.basis, fit.white_resid)
    return gain_given(probe, np.hstack([fit.basis, best.basis]), fit.white_resid - best.white_contribution)


#: Simulated datasets for ``excess_if_effect_true``, and the seed of their own generator (the
#: workflow's generator is left alone, so the rest of a run draws what it drew before).
EXCESS_DRAWS = 400
EXCESS_SEED = 29


def excess_if_effect_true(fit: Fit, probe: Probe, best: CandidateScore) -> float:
    """The (1 − α) point of the probe's penalised excess over the effect when the effect is true.

    A probe nearly collinear with an effect (on a profile with few rate levels, a rate² on
    one sign and the catalogue's ω² correlate at 0.98–0.99 once the base's scale factor has
    taken the odd half) explains about as much as the effect whichever of them is in the
    data; which one comes out ahead is then noise (a 10σ sf_nonlinearity_quadratic lost to
    the one-sign probe in 3 of 8 runs on a 3-level profile, by Δχ² 1–6). A parametric
    bootstrap of the effect hypothesis: the effect's fitted whitened contribution plus
    standard normal draws, the probe (its best instance) and the effect (its fitted shape,
    linearised: the direction of its contribution) refitted to each, the probe's penalised
    Δχ² less the effect's. Only an excess beyond what the effect itself produces at the α
    level rejects the effect in favour of the probe, as every claim must clear its own null.
    """
    signal = best.white_contribution
    if signal is None or not float(signal @ signal) > 0:
        return 0.0
    signal = signal - fit.basis @ (fit.basis.T @ signal)
    draws = np.random.default_rng(EXCESS_SEED).standard_normal((len(signal), EXCESS_DRAWS))
    data = signal[:, None] + draws
    effect_basis = (best.basis if not best.structural
                    else (signal / np.linalg.norm(signal))[:, None])
    probe_basis = _orthonormal(probe.white_columns - fit.basis @ (fit.basis.T @ probe.white_columns))
    penalty = probe.delta_chi2 - probe.penalised_against(best.dof, len(signal))
    excess = (np.sum((probe_basis.T @ data) ** 2, axis=0) - penalty
              - np.sum((effect_basis.T @ data) ** 2, axis=0))
    return order_statistic_quantile(excess, 1.0 - ALPHA)


def _orthonormal(columns: np.ndarray) -> np.ndarray:
    q, r = np.linalg.qr(columns)
    good = np.abs(np.diag(r)) > 1e-7 * max(float(np.abs(np.diag(r)).max()), 1e-300)
    return q[:, good]


def outside_odds(probes: list[Probe], dof: int, delta_chi2: float, n_bins: int,
                 beside: list[float] | None = None) -> tuple[float, Probe | None]:
    """Σ over the probes of the odds of "the probe instead of the effect", and the largest term's probe.

    The probes join the look-alike split (a flat prior, as in lookalikes.probabilities):
    a named effect that a shape outside the catalogue explains about as well cannot be
    stated at 0.99 (a rate² on one rate sign and the catalogue's ω² were equal, Δχ² 125
    against 125, on a profile dominated by ±300 deg/s dwells). A probe's term is
    L_probe / (L_effect + L_both), each L = exp(penalised Δχ² / 2) (BIC, the search penalty
    2 ln M on the probe): the effect is real in the model with both too. ``beside`` holds
    each probe's Δχ² fitted beside the effect (``gain_beside``); without it L_both is left
    out (the probe only as an alternative). A probe that explains other structure than the
    effect is then no rival: a 10σ bias ∝ table acceleration (probe Δχ² 126) took a real
    10σ temp_rate_bias (Δχ² 71) to probability 10⁻¹² when its term was L_probe / L_effect.
    """
    n_bins = max(n_bins, 2)

    def term(p: Probe, k: int) -> float:
        alone = math.exp(min((p.penalised_against(dof, n_bins) - delta_chi2) / 2.0, 50.0))
        if beside is None:
            return alone
        both = beside[k] - 2.0 * math.log(max(p.n_candidates, 1)) - p.dof * math.log(n_bins)
        return alone / (1.0 + math.exp(min(both / 2.0, 50.0)))

    terms = [(term(p, k), p) for k, p in enumerate(probes)]
    if not terms:
        return 0.0, None
    return sum(t for t, _ in terms), max(terms, key=lambda tp: tp[0])[1]


def preempting_probe(ctx: Context, fit: Fit, probes: list[Probe], compete: bool, best: str,
                     scores: dict[str, EffectScores], threshold: float,
                     markov_stationary: bool = False) -> Probe | None:
    """The first significant probe (strongest first) that explains the data better than ``best``.

    None when probes do not ``compete`` with the candidate (a spectral line is sharper than any).

    Against a Markov bias whose reading is stationary over the record, a probe must also
    hold in each half of the record on its own (``holds_in_both_halves``): cross-validation
    between the halves. A stationary process's wander can be caught by a bias step late in
    the record (τ = 1000 s on a 1-hour record, which the step left no Markov bias behind);
    a real ramp, curve or sinusoid shows in both halves.
    """
    if not compete:
        return None
    for probe in significant_by_strength(probes):
        if best == MARKOV:
            if ((not markov_stationary or holds_in_both_halves(fit, probe))
                    and probe_explains_markov(ctx, fit, probe)):
                return probe
        elif probe_beats_effect(fit, probe, scores[best], threshold):
            return probe
    return None


def holds_in_both_halves(fit: Fit, probe: Probe) -> bool:
    """Whether the probe's fitted shape is significant (α, one column) in each half on its own."""
    perp = probe.white_columns - fit.basis @ (fit.basis.T @ probe.white_columns)
    coef, *_ = np.linalg.lstsq(perp, fit.white_resid, rcond=None)
    shape = perp @ coef
    half = len(shape) // 2
    for part in (slice(0, half), slice(half, None)):
        norm2 = float(shape[part] @ shape[part])
        if not norm2 > 0:
            return False
        gain = float(shape[part] @ fit.white_resid[part]) ** 2 / norm2
        if score_from_delta(gain, 1) <= -math.log10(ALPHA):
            return False
    return True


def markov_survives(ctx: Context, fit: Fit, spec: EffectSpec) -> bool:
    """Whether the Markov test stays significant (`markov_left`) once ``spec`` is fitted too.

    Settles a slow shape that the Markov noise explains away (``explained_by_markov``)
    but that holds more likelihood than the Markov bias (Δχ² 155 against LR 138 for a
    quadratic caught in two wiggles of a τ = 1000 s process): a real shape, once
    fitted, leaves no Markov bias behind; a look-alike leaves the process's other
    frequencies, and then the Markov bias is the explanation.
    """
    return markov_left(markov_test(ctx, ctx.fit(fit.model.with_effect(spec))))


def markov_left(rest: StochasticCandidate) -> bool:
    """Whether a Markov bias is still significant in a residual, by the Markov test's own null.

    One test of one residual, so its own (1 − α) point, not the library threshold (the
    maximum over every effect, searched): after a real bias or scale-factor step is fitted
    the Markov test's p-value is 0.10–1.0 (20 runs), after a sinusoid fitted to a
    τ = 1000 s Markov bias 0.00–0.02, yet both had been under the library threshold.
    """
    return rest.score > order_statistic_quantile(rest.null_scores(), 1.0 - ALPHA)


def structure_behind_markov(ctx: Context, model: GyroModel, fit: Fit, markov: StochasticCandidate,
                             scores: dict[str, EffectScores], threshold: float) -> str | None:
    """The deterministic effect whose fit leaves no Markov bias, when the Markov bias outscored it.

    The mirror of ``explained_by_markov``. The Markov test reads one-second bins of
    the full-rate residual, the catalogue the coarser GLS bins: a structure that is
    sharp in time (a dead zone's slew samples, each a 36σ spike in its second) looks to
    the Markov test like a fast process with a likelihood ratio ten times the
    structure's own Δχ² (9300 against 840 on a 100 Hz log with a 0.3 deg/s dead zone,
    where the Markov bias, a spurious line and then the dead zone were named).
    The strongest significant deterministic effect is fitted; if no Markov bias is left
    in that residual (``markov_left``) while the effect, rescored under the noise with
    the Markov process, stays above the threshold, the structure is the explanation.
    """
    rivals = {name: s for name, s in scores.items() if s.score > threshold}
    if not rivals:
        return None
    name = max(rivals, key=lambda n: rivals[n].score)
    refined = refine_shape(rivals[name], ctx.builder, fit, ctx.whitener, ctx.y_bins,
                           ctx.space)
    if markov_survives(ctx, fit, refined.spec(fit.model)):
        return None
    return None if explained_by_markov(ctx, model, markov, rivals[name], threshold) else name


def markov_stationary(ctx: Context, fit: Fit, markov: StochasticCandidate) -> Stationarity:
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    return stationarity_test(ctx.noise, bins.mean(ctx.resid_full(fit)), bins, ctx.fs_hz,
                             markov, ctx.rng, ctx.n_null, ALPHA)


def unless_nonstationary(ctx: Context, fit: Fit, markov: StochasticCandidate, test: Stationarity,
                         ranked: dict[str, float], scores: dict[str, EffectScores]
                         ) -> tuple[str | None, str | None]:
    """(MARKOV, None) if the process is stationary over the record; else (the next best or None, why).

    The separation of a stationary random process from deterministic slow structure
    (stochastic.stationarity_test): a process whose power differs between the record's
    parts beyond what one process shows at the α level is not a Markov bias, whatever its
    likelihood; the structure is reported as unexplained unless a catalogue effect or a
    probe accounts for it. The second value says what the refused process looked like.
    """
    if test.stationary:
        return MARKOV, None
    parts = ", ".join(f"{r:.2g}" for r in test.power_ratio)
    nonstationary = (
        f"slow structure that a Markov bias (σ {markov.params['sigma_dph']:.3g} deg/h, τ "
        f"{markov.params['tau_s']:.0f} s) would fit, but not stationary: its power in the record's "
        f"halves is {parts} × the whole record's (test statistic {test.statistic:.1f}, limit "
        f"{test.limit:.1f} at α = {ALPHA:g})")
    return next_best_or_none(ctx, fit, ranked, scores), nonstationary


def unless_not_gauss_markov(ctx: Context, fit: Fit, markov: StochasticCandidate, ranked: dict[str, float],
                            scores: dict[str, EffectScores]) -> tuple[str | None, str | None]:
    """(MARKOV, None) if the process is Gauss–Markov in its levels and its spectrum; else as above.

    A stationary process can still be no Gauss–Markov bias: a two-level switching bias
    has a Lorentzian spectrum, a flicker excess a power law (process_shape.py).
    """
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    verdict = gauss_markov_shape(ctx.noise, bins, ctx.fs_hz, bins.mean(ctx.resid_full(fit)), markov)
    if verdict.why is None:
        return MARKOV, None
    return next_best_or_none(ctx, fit, ranked, scores), verdict.why


def next_best_or_none(ctx: Context, fit: Fit, ranked: dict[str, float], scores: dict[str, EffectScores]
                      ) -> str | None:
    """The next best catalogue effect once the Markov bias is refused, if it accounts for the structure."""
    rest = {name: score for name, score in ranked.items() if name in scores}
    if not rest:
        return None
    best = max(rest, key=rest.get)
    # the next best (bin-level) effect is named only if it accounts for the slow structure: once
    # it is fitted no Markov bias is left (a linear ramp under a bias accelerating with time
    # leaves one); a spectral line cannot account for slow structure
    if markov_survives(ctx, fit, scores[best].best.spec(fit.model)):
        return None
    return best
