"""The discrepancy workflow: refit, estimate the noise, score the catalogue, add, repeat.

1. Refit the model's own linear parameters (bias, SF error, tempcos, any
   effect amplitudes) to the bin means by GLS, so what remains is structure
   the model lacks rather than wrong numbers.
2. Estimate the noise on the quiet segments of that residual and build the
   whitening.
3. Score every catalogue effect the model lacks (shape parameters by grid and
   a bounded scalar search), periodic interference on the full-rate spectrum,
   a Gauss–Markov bias by the Whittle likelihood of the whole residual
   (stochastic.py; an accepted one joins the noise model and the whitening;
   named only if stationary, Gauss–Markov in shape, process_shape.py, and tied
   to nothing the rig logged, markov_covariates.py),
   and the out-of-catalogue probes (probes.py: a bias step, a scale-factor step,
   a slow sinusoid of unknown period), which compete on equal footing.
4. Calibrate the acceptance threshold by simulation: effect-free data from
   the refitted model and the noise model, the maximum score over the whole
   library per dataset, its (1 − α) quantile (a Markov bias's with the Markov
   test's null refined as its data is, markov_threshold.py). Accept the best effect only
   above it, and only if a generic step does not explain the data clearly
   better (then the structure is outside the catalogue and is reported, not
   named after its nearest neighbour).
5. Add it, refit everything jointly (shape parameters of found effects too),
   repeat up to ``max_effects``; then measure the gap before and after
   beside the noise floor and decide whether anything is left unexplained.
6. Judge whether the named effects are the whole account (adequacy.py): the
   probes once more on the final residual, their best score against the
   family-wise threshold on effect-free draws; structure left behind makes
   the result unexplained and takes the probability of a named effect it
   replaces below 0.5. The bin means cannot show a white-noise level that
   changes with |rate|, temperature or time: noise_level.py tests the
   full-rate residual's within-window scatter for it, with the same result.
   Nor a periodic line whose frequency drifts with temperature or time
   (line_drift.py), which the fixed-line search smears over many bins and
   passes over: when one is there, the result is unexplained with the line
   and its drift in ``where``, and a periodic_interference named within its
   frequencies loses its claim. Nor single-sample outliers and spikes, which the
   scatter test clips (outliers.py reads the tails of the full-rate residual, with
   the same result). Nor whether a named effect keeps one size over the record
   (split_check.py): a catalogue law fitted to foreign structure needs
   another amplitude in another part (time, temperature, rate sign, |rate|); then
   the result is unexplained and that effect's probability falls below 0.5. Nor
   structure local in time (localized.py: window means at every dyadic scale against
   the noise model's variance there) or a periodic waveform that is not a sinusoid
   (harmonic_comb.py: harmonics of one fundamental), with the same result.

The code reads as that pipeline: ``_noise_pass`` → ``_search_pass`` (rounds of
``_search_round``) → ``_gap_pass`` (with ``_adequacy_pass`` and ``drifting_line``), each returning what the next needs. The
candidate effects sit behind one interface in a registry (candidates.py), the
rules that arbitrate between them in arbitration.py, the log's shared inputs
and whitening in context.py, the result types in result.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from threadpoolctl import threadpool_limits

from gyrocal.analysis.discrepancy.adequacy import NOT_JUDGED, Adequacy, adequacy, judged
from gyrocal.analysis.discrepancy.arbitration import (
    GAP_CHECK_MARGIN,
    explained_by_markov,
    gap_open,
    markov_stationary,
    markov_survives,
    preempting_probe,
    structure_behind_markov,
    unless_nonstationary,
    unless_not_gauss_markov,
)
from gyrocal.analysis.discrepancy.candidates import (
    KINDS,
    PERIODIC,
    QUANTIZATION,
    Candidate,
    CatalogueCandidate,
    GapInputs,
    MarkovCandidate,
    SearchState,
    Weighing,
    kind_of,
)
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.g1_null import g1_quantile
from gyrocal.analysis.discrepancy.gap import (
    FLOOR_PROBABILITY,
    AllanRatios,
    Metric,
    SegmentGeometry,
    choose_primary,
    describe_remainder,
    expected_max_exponential,
    g1,
    max_exponential_quantile,
    segment_rms,
)
from gyrocal.analysis.discrepancy.harmonic_comb import with_comb
from gyrocal.analysis.discrepancy.line_drift import drifting_line
from gyrocal.analysis.discrepancy.localized import with_localized
from gyrocal.analysis.discrepancy.markov_covariates import unless_tied_to_covariates
from gyrocal.analysis.discrepancy.markov_shapes import unless_deterministic_shape
from gyrocal.analysis.discrepancy.markov_threshold import Thresholds, library_thresholds
from gyrocal.analysis.discrepancy.noise_level import judged_by_level, noise_level_test
from gyrocal.analysis.discrepancy.noise_model import NoiseEstimate, NoiseModel, estimate_noise
from gyrocal.analysis.discrepancy.order_track import with_order_line
from gyrocal.analysis.discrepancy.outliers import with_spikes
from gyrocal.analysis.discrepancy.own_gap import EffectGap
from gyrocal.analysis.discrepancy.periodic import REFINEMENT_FACTOR, PeriodicScan, sine_dph
from gyrocal.analysis.discrepancy.probes import Probe, ProbeKind, all_probes, strongest
from gyrocal.analysis.discrepancy.quantization import detect_pulse
from gyrocal.analysis.discrepancy.result import ALPHA, DiscrepancyResult, FoundEffect, Iteration
from gyrocal.analysis.discrepancy.scoring import Fit, Whitener
from gyrocal.analysis.discrepancy.split_check import judged_by_split, split_check
from gyrocal.analysis.discrepancy.stochastic import FINE_BIN_S, MARKOV, StochasticCandidate
from gyrocal.analysis.measured_log import MeasuredLog
from gyrocal.models.gyro_model import EffectSpec, GyroModel
from gyrocal.models.indicated import indicated_rate

__all__ = ["ALPHA", "DiscrepancyResult", "FoundEffect", "Iteration", "analyse"]

#: G1 after the refit above this quantile of its effect-free distribution is "unexplained" (the exact
#: point, g1_null.py: the largest of the 60 shared draws was exceeded by 1/61 of effect-free records).
UNEXPLAINED_LEVEL = 0.99
#: Effect-free draws the Allan mismatches' floors come from (each Allan curve costs ~1 ms idle, ~0.1 s
#: on a loaded machine); the 19th of 20 is their 90 % point (P(new ≤ it) = 19/21).
ALLAN_NULL_DRAWS = 20


def analyse(model: GyroModel, log: MeasuredLog, seed: int = 0, n_null: int = 500,
            max_effects: int = 3, max_bins: int = 2000,
            progress: Callable[[str], None] | None = None) -> DiscrepancyResult:
    """Run the whole workflow on a measured log; see the module docstring.

    ``seed`` makes the simulated threshold calibration reproducible;
    ``n_null`` is the number of effect-free datasets it simulates;
    ``max_bins`` bounds the size of the GLS (bins are at least 1 s);
    ``progress`` receives a line as each pass starts (the command prints them on stderr).
    """
    # One BLAS thread: the matrices are a few thousand rows, where OpenBLAS's threads gain
    # little and, on a shared 2-core machine, spin against other processes (measured: a
    # 1-hour log took 24 s threaded, 1.8 s single-threaded). threadpoolctl sets it for
    # numpy's and scipy's BLAS alike and restores it afterwards.
    with threadpool_limits(limits=1, user_api="blas"):
        return _analyse(model, log, seed, n_null, max_effects, max_bins,
                        progress or (lambda _line: None))


def _analyse(model: GyroModel, log: MeasuredLog, seed: int, n_null: int,
             max_effects: int, max_bins: int, progress: Callable[[str], None]
             ) -> DiscrepancyResult:
    """The workflow's passes: noise model, effect search, gap metrics, what is left."""
    progress(f"segments and bins of {len(log.t_s):,} samples")
    ctx = Context(model, log, seed, n_null, max_bins)
    progress(f"noise model from {len(ctx.segments.quiet_slices(ctx.fs_hz))} quiet segments")
    noise = _noise_pass(ctx, model)
    search = _search_pass(ctx, noise.state, max_effects, progress)
    progress("gap metrics before and after")
    return _gap_pass(ctx, model, noise, search)


@dataclass(frozen=True)
class NoiseOutcome:
    """The noise pass's result: the estimate, the noise model before any Markov bias, the state."""

    estimate: NoiseEstimate
    before: NoiseModel
    state: SearchState


def _noise_pass(ctx: Context, model: GyroModel) -> NoiseOutcome:
    """Noise from the quiet segments; quantization from the output lattice; a Markov hump."""
    prior = NoiseModel.of_model(model)
    # the first refit only feeds the quiet-segment noise estimate: ordinary least squares will do
    ctx.whitener = Whitener(np.eye(ctx.bins.n_bins))
    first = ctx.fit(model)
    noise_est = estimate_noise(ctx.resid_full(first), ctx.fs_hz, ctx.segments.quiet_slices(ctx.fs_hz), prior,
                               allow_markov=not model.has_effect(MARKOV), long_terms=False,
                               markov_min_tau_s=FINE_BIN_S)
    # A Markov bias is judged over the whole record (stochastic.py), not from the quiet
    # segments' Allan hump, which misses correlation times longer than those segments. The
    # hump is still allowed in the quiet fit, so that N and Q are not bent to absorb it
    # (σ 1.2 deg/h, τ 8 s came back as τ 3.7 s when Q had soaked up part of the process),
    # but the term itself is left out of the noise model.
    noise = replace(noise_est.model, markov_sigma_dph=prior.markov_sigma_dph,
                    markov_tau_s=prior.markov_tau_s)
    before = noise
    state = SearchState(model, noise)
    lattice = None if model.has_effect(QUANTIZATION) else detect_pulse(ctx.log.gyro, model.scale_factor,
                                                                        ctx.fs_hz)
    if lattice is not None:
        spec = EffectSpec(QUANTIZATION, {"pulse_arcsec": lattice.pulse_arcsec})
        # white angle noise of a pulse q: Q = q/√12 (IEEE Std 647); keeps the whitening honest
        noise = replace(noise, quantization_arcsec=max(noise.quantization_arcsec,
                                                       lattice.pulse_arcsec / math.sqrt(12.0)))
        found = FoundEffect(QUANTIZATION, dict(spec.params), lattice.on_lattice, [], "", 0.0, 0.0, 0.0)
        state = replace(state, current=model.with_effect(spec), noise=noise, lattice=lattice, found=(found,))
        state = state.noted(
            f"quantization: {100 * lattice.on_lattice:.2f} % of the samples are whole multiples of a "
            f"{lattice.pulse_arcsec:.4g}\" pulse ({lattice.levels} output levels): found from the output "
            "lattice, not scored by χ²; lines whose angle amplitude is within two pulses are its beat, "
            "not interference")
    ctx.use_noise(noise, f"model {model.name or '(unnamed)'}")
    state = state.noted(f"noise model: {noise_est.source}")
    if ctx.log.sensor_temp_c is not None:
        state = state.noted("the log has sensor_temp_c: thermal_lag is not searched (the measured sensor "
                            "temperature is used as it is)")
    return NoiseOutcome(noise_est, before, state)


@dataclass(frozen=True)
class SearchOutcome:
    """The search pass's result: the final state, every round, and why the last one stopped."""

    state: SearchState
    iterations: tuple[Iteration, ...]
    preempted: Probe | None = None
    #: set when the last round's Markov candidate failed the stationarity test: what it saw
    nonstationary: str | None = None


@dataclass(frozen=True)
class RoundOutcome:
    state: SearchState
    iteration: Iteration | None
    accepted: bool
    preempted: Probe | None = None
    nonstationary: str | None = None


def _search_pass(ctx: Context, state: SearchState, max_effects: int,
                 progress: Callable[[str], None]) -> SearchOutcome:
    """Name effects one at a time while the best candidate beats the simulated threshold."""
    iterations: list[Iteration] = []
    last = None
    for iteration in range(1, max_effects + 1):
        progress(f"effect search, round {iteration}: scoring the catalogue, {ctx.n_null} "
                 "simulated effect-free datasets for the threshold")
        last = _search_round(ctx, state, iteration)
        state = last.state
        if last.iteration is not None:
            iterations.append(last.iteration)
        if not last.accepted:
            break
    if last is None:
        return SearchOutcome(state, ())
    return SearchOutcome(state, tuple(iterations), last.preempted, last.nonstationary)


@dataclass(frozen=True)
class Choice:
    """A round's best candidate after the arbitration, and what stopped it if anything."""

    best: str | None
    preempting: Probe | None = None
    nonstationary: str | None = None


def _search_round(ctx: Context, state: SearchState, iteration: int) -> RoundOutcome:
    """One round: propose, threshold, arbitrate, and name the winner if it clears every test."""
    fit = ctx.fit(state.current)
    z = ctx.rng.standard_normal((ctx.bins.n_bins, ctx.n_null))
    candidates = [c for kind in KINDS for c in kind.propose(ctx, state, fit)]
    # the catalogue's threshold and the Markov candidate's (markov_threshold.py)
    thresholds = library_thresholds(candidates, fit, z, ctx.rng, ALPHA / iteration)
    threshold = thresholds.catalogue
    probes = all_probes(fit, ctx.whitener, ctx.bins, ctx.probe_bins, z, ALPHA)
    if not candidates:
        return RoundOutcome(state, None, False)
    ranked = {c.name: c.score for c in candidates}
    record = Iteration(ranked, {c.name: c.delta_chi2 for c in candidates}, threshold, None, probes)
    by_name = {c.name: c for c in candidates}
    choice = _choose(ctx, state, fit, by_name, thresholds, probes)
    if choice.nonstationary is not None:
        state = state.noted(f"markov_bias not named: {choice.nonstationary}")
    best = choice.best
    threshold = thresholds.of(best)
    if best is None or ranked[best] <= threshold or choice.preempting is not None:
        return RoundOutcome(state, record, False, choice.preempting if best is not None else None,
                            choice.nonstationary)
    candidate = by_name[best]
    if not (not candidate.checks_gap or ranked[best] - threshold >= GAP_CHECK_MARGIN
            or gap_open(ctx, fit, z)):
        state = state.noted(f"{best} scored {ranked[best]:.1f} (threshold {threshold:.1f}) but no gap metric "
                            "of the residual is above its noise floor: not named")
        return RoundOutcome(state, record, False, None, choice.nonstationary)
    scores = {c.name: c.scores for c in candidates if isinstance(c, CatalogueCandidate)}
    state = candidate.admit(ctx, state, Weighing(fit, threshold, probes, scores))
    return RoundOutcome(state, replace(record, accepted=best), True, None, choice.nonstationary)


def _choose(ctx: Context, state: SearchState, fit: Fit, by_name: dict[str, Candidate], thresholds: Thresholds,
            probes: list[Probe]) -> Choice:
    """The best candidate once a Markov bias and deterministic structure have been weighed.

    A Markov bias must be stationary over the record, leave no probe the sharper
    reading (arbitration.py), be Gauss–Markov in its levels and its spectrum, not a
    switching bias or a flicker excess (process_shape.py), and follow nothing the rig
    logged (markov_covariates.py) nor a deterministic slow shape (markov_shapes.py); any other best candidate
    yields to a probe that explains the data better.
    """
    ranked = {name: c.score for name, c in by_name.items()}
    scores = {name: c.scores for name, c in by_name.items() if isinstance(c, CatalogueCandidate)}
    markov = by_name.get(MARKOV)
    test = markov.test if isinstance(markov, MarkovCandidate) else None
    threshold = thresholds.catalogue
    best = _markov_or_structure(ctx, state, fit, by_name, test, thresholds)
    if ranked[best] <= thresholds.of(best):
        return Choice(best)
    if best != MARKOV:
        return Choice(best, preempting_probe(ctx, fit, probes, by_name[best].probes_compete, best, scores,
                                             threshold))
    stationary = markov_stationary(ctx, fit, test)
    preempting = preempting_probe(ctx, fit, probes, True, best, scores, threshold, stationary.stationary)
    if preempting is not None:
        return Choice(best, preempting)
    best, nonstationary = unless_nonstationary(ctx, fit, test, stationary, ranked, scores)
    if best == MARKOV:   # stationary; but a switching bias or a flicker excess is not Gauss–Markov
        best, nonstationary = unless_not_gauss_markov(ctx, fit, test, ranked, scores)
    if best == MARKOV:   # nor is slow structure that follows what the rig logged (markov_covariates.py)
        best, nonstationary = unless_tied_to_covariates(ctx, fit, test, ranked, scores)
    if best == MARKOV:   # nor is a deterministic slow shape a Markov would imitate (markov_shapes.py)
        best, nonstationary = unless_deterministic_shape(ctx, fit, test, ranked, scores)
    if best is None or best == MARKOV or ranked[best] <= threshold:
        return Choice(best, None, nonstationary)
    return Choice(best, preempting_probe(ctx, fit, probes, by_name[best].probes_compete, best, scores,
                                         threshold), nonstationary)


def _markov_or_structure(ctx: Context, state: SearchState, fit: Fit, by_name: dict[str, Candidate],
                         markov: StochasticCandidate | None, thresholds: Thresholds) -> str:
    """The top-scoring candidate, unless a Markov bias and a deterministic shape explain each other.

    A slow shape that outscored the Markov bias but is only its wander gives way to it
    (``explained_by_markov``, ``markov_survives``); a Markov bias that outscored a
    sharp structure leaves nothing once the structure is fitted (``structure_behind_markov``).
    """
    best = max(by_name, key=lambda name: by_name[name].score)
    if markov is None:
        return best
    scores = {name: c.scores for name, c in by_name.items() if isinstance(c, CatalogueCandidate)}
    rival = by_name[best]
    if isinstance(rival, CatalogueCandidate):
        if (markov.score > thresholds.markov and explained_by_markov(ctx, state.current, markov, rival.scores, thresholds.catalogue)
                and ((markov.lr >= rival.delta_chi2 and not markov.at_rrw_limit)
                     or markov_survives(ctx, fit, rival.scores.best.spec(fit.model)))):
            return MARKOV
        return best
    if best == MARKOV:
        return structure_behind_markov(ctx, state.current, fit, markov, scores, thresholds.catalogue) or best
    return best


def _gap_pass(ctx: Context, model: GyroModel, noise: NoiseOutcome, search: SearchOutcome) -> DiscrepancyResult:
    """The gap metrics before and after against their simulated null, each effect's own, what is left."""
    state = search.state
    after = ctx.fit(state.current)
    updated = _final_periodic(ctx, after)
    if updated is not after.model:
        after = ctx.fit(updated)
    found = [replace(f, parameters=dict(after.model.effect(f.name).params)) for f in state.found]
    before = ctx.fit(model)
    seg_of_bin = ctx.segments.bin_index(ctx.bins)
    geometry = SegmentGeometry.of(seg_of_bin, ctx.whitener.covariance)
    z = ctx.rng.standard_normal((ctx.bins.n_bins, 60))
    null_resid = ctx.whitener.colour(z - after.basis @ (after.basis.T @ z))
    metrics, null_g1, allan = _whole_record_metrics(ctx, before, after, geometry, null_resid, noise.before, state.noise)
    scan_before, scan_after = ctx.scan(before), ctx.scan(after)
    if scan_before is not None and scan_after is not None:
        m = int(scan_after.n_freqs / REFINEMENT_FACTOR)
        metrics["spectrum_peak"] = Metric(scan_before.peak_ratio, scan_after.peak_ratio,
                                          max_exponential_quantile(m, FLOOR_PROBABILITY),
                                          math.pi / math.sqrt(6.0), "1 (periodogram / noise PSD)",
                                          "largest line of the full-rate residual over the noise PSD",
                                          expected_max_exponential(m))
    gaps = _effect_gaps(ctx, found, GapInputs(model, before, after, null_resid, geometry, metrics, allan))
    for gap in gaps:
        metrics.update(gap.metrics)
    # the headline is the first named effect's own metric (issue 29: a whole-record metric may
    # not move at all for the effect that was named)
    heads = [gap.headline for gap in gaps if gap.headline in metrics]
    primary = heads[0] if heads else choose_primary(metrics, bool(found))
    found, test, last_probe = _adequacy_pass(ctx, after, found)
    level = noise_level_test(ctx, after)
    found = judged_by_level(ctx, after, found, level)
    found, drift = drifting_line(ctx, after, found)
    split = split_check(ctx, after, found)   # split_check.py: a named effect whose size differs by part
    found = judged_by_split(found, split)
    structure_left = (search.preempted is not None or search.nonstationary is not None or test.inadequate
                      or metrics["g1_segment_mean"].after > g1_quantile(ctx.whitener, after.basis, geometry,
                                                                       UNEXPLAINED_LEVEL))
    unexplained = structure_left or level.fires or drift is not None or split.fires
    signals = _signals(ctx, after.model)
    where, notes = "", list(state.notes)
    if test.inadequate and test.probe is not None:
        notes.append(f"the named effects leave {test.probe.describe()} behind (score {test.statistic:.1f}, "
                     f"family-wise threshold {test.threshold:.1f} over {ctx.n_null} effect-free draws): "
                     "they are not the whole account")
    if structure_left:
        where, remainder_notes = _remainder(ctx, search, after, geometry, signals, scan_after, last_probe)
        notes += remainder_notes
    if level.fires:
        where = f"{level.description}; {where}" if where else level.description
    notes.append(level.note)
    if drift is not None:   # line_drift.py: a line the fixed-line search smears over many bins
        where = f"{drift.describe()}; {where}" if where else drift.describe()
    if split.fires:
        where = f"{split.describe()}; {where}" if where else split.describe()
    return with_comb(ctx, after, with_localized(ctx, after, with_order_line(ctx, after, with_spikes(ctx, after, DiscrepancyResult(
        found, unexplained, where, metrics, primary, model, after.model, noise.estimate,
        list(search.iterations), ctx.bins, ctx.segments, np.unique(seg_of_bin), geometry,
        before.resid_bins, after.resid_bins, signals, scan_before, scan_after, noise.before,
        float(ctx.log.t_s[0]), notes, {gap.effect: gap.headline for gap in gaps})))))  # lines, spikes, windows, combs


def _adequacy_pass(ctx: Context, after: Fit, found: list[FoundEffect]
                   ) -> tuple[list[FoundEffect], Adequacy, Probe | None]:
    """The probes once more on the final residual: what the named effects leave (adequacy.py).

    Returns the named effects with their probabilities after the test, the test, and the
    probe to describe what is left (the test's when it fired, else the strongest significant).
    """
    probes = all_probes(after, ctx.whitener, ctx.bins, ctx.probe_bins,
                        ctx.rng.standard_normal((ctx.bins.n_bins, ctx.n_null)), ALPHA)
    if not any(f.name not in NOT_JUDGED for f in found):
        return found, Adequacy(0.0, math.inf, None), strongest(probes)
    test = adequacy(probes, ALPHA)
    return judged(ctx, after, found, test), test, test.probe if test.inadequate else strongest(probes)


def _whole_record_metrics(ctx: Context, before: Fit, after: Fit, geometry: SegmentGeometry,
                          null_resid: np.ndarray, noise_before: NoiseModel, noise: NoiseModel
                          ) -> tuple[dict[str, Metric], np.ndarray, AllanRatios]:
    """G1, the segment-mean RMS and the Allan mismatch, before and after; G1's null draws; the Allan ratios."""
    metrics: dict[str, Metric] = {}
    null_g1 = g1(geometry, null_resid)
    metrics["g1_segment_mean"] = Metric.of_null(
        g1(geometry, before.resid_bins), g1(geometry, after.resid_bins), null_g1, "1 (mean of z²)",
        "G1 over every segment: (segment mean / its standard error)², averaged")
    metrics["segment_mean_rms_dph"] = Metric.of_null(
        segment_rms(geometry, before.resid_bins), segment_rms(geometry, after.resid_bins),
        segment_rms(geometry, null_resid), "deg/h", "RMS of the residual's segment means")
    allan = AllanRatios.of(before.resid_bins, after.resid_bins, null_resid[:, :ALLAN_NULL_DRAWS], ctx.bins,
                           noise_before, noise)
    metrics["allan_mismatch"] = allan.mismatch()
    return metrics, null_g1, allan


def _effect_gaps(ctx: Context, found: list[FoundEffect], inputs: GapInputs) -> list[EffectGap]:
    """Each named effect's gap in its own domain (its kind's ``own_gap``), in the order they were named."""
    gaps = [kind_of(f.name).own_gap(ctx, f.name, inputs) for f in found]
    return [gap for gap in gaps if gap is not None]


def _remainder(ctx: Context, search: SearchOutcome, after: Fit, geometry: SegmentGeometry,
               signals: dict[str, np.ndarray], scan_after: PeriodicScan | None,
               last_probe: Probe | None) -> tuple[str, list[str]]:
    """Where the unexplained structure is (``where``) and the notes that say what it looks like."""
    preempted, notes = search.preempted, []
    probe_info = preempted or last_probe
    step_info = probe_info if probe_info is not None and probe_info.kind is ProbeKind.BIAS_STEP else None
    line = None
    if scan_after is not None and scan_after.score > 2.0 and not after.model.has_effect(PERIODIC):
        line = (scan_after.freq_hz, scan_after.amplitude_dph)
    seg_of_bin = ctx.segments.bin_index(ctx.bins)
    where = describe_remainder(after.resid_bins, ctx.bins, geometry, ctx.segments.names, np.unique(seg_of_bin),
                               signals, None if step_info is None else (step_info.time_s, step_info.size_dph),
                               line)
    if probe_info is not None and step_info is None:
        where = f"{probe_info.describe()} (Δχ² {probe_info.delta_chi2:.1f}); {where}"
    if search.nonstationary is not None:   # what the refused Markov process looked like comes first
        where = f"{search.nonstationary}; {where}"
    if preempted is not None:
        notes.append(f"{preempted.describe()} explains the data better than any catalogue "
                     f"effect (Δχ² {preempted.delta_chi2:.1f}); nothing was named")
    elif probe_info is not None and step_info is None:
        notes.append(f"what is left looks like {probe_info.describe()} (Δχ² {probe_info.delta_chi2:.1f})")
    return where, notes


def _signals(ctx: Context, model: GyroModel) -> dict[str, np.ndarray]:
    state = indicated_rate(model, ctx.inputs)
    b = ctx.bins
    rate = ctx.inputs.table_rate_dps
    return {
        "chamber temperature (degC)": b.mean(ctx.inputs.chamber_temp_c),
        "sensor temperature rate (degC/min)": b.mean(state.sensor_temp_rate_c_per_min),
        "table rate (deg/s)": b.mean(rate),
        "|table rate| (deg/s)": b.mean(np.abs(rate)),
        "cos(table angle)": b.mean(np.cos(np.deg2rad(state.table_angle_deg))),
        "time since power-on (s)": b.centre_s.copy(),
    }


def _final_periodic(ctx: Context, fit: Fit) -> GyroModel:
    """Re-estimate a found line's amplitude on the full-rate residual of the joint refit."""
    spec = fit.model.effect(PERIODIC)
    if spec is None:
        return fit.model
    t = ctx.log.t_s
    line = sine_dph(spec["freq_hz"], 1.0, t)
    resid = ctx.resid_full(fit) + spec["amplitude_dph"] * line
    resid = resid - resid.mean()
    amplitude = float(line @ resid / (line @ line))
    return fit.model.with_effect(EffectSpec(spec.name, {**spec.params, "amplitude_dph": amplitude}))
