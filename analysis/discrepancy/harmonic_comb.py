"""A periodic waveform that is not a sinusoid: harmonics of one fundamental in the final residual (issue 29).

The catalogue's periodic_interference and the slow-sinusoid probe are one
sinusoid each. A pulse train (valve clicks, a heater cycling, a periodic
burst), a sawtooth (integrator resets) or a square wave spreads its power over
many harmonics of one fundamental, none of them strong by itself: on the fifth
held-out set 1-s pulses every 90 s were not seen at all on two profiles, and on
a third one harmonic was named periodic_interference at ≥ 0.8.

What is measured. The periodogram of the final refit's whitened binned residual
(L⁻¹r: under the noise model and refit N(0, I − QQᵀ), so its periodogram is
Exp(1) per frequency away from the fitted span, whatever the noise's colour;
a stationary whitening keeps a periodic waveform periodic), zero-padded
``PAD`` times. For each trial fundamental f0 (from two periods in the record
up, on a grid fine enough that its K-th harmonic is read within a fifth of a
Fourier bin) and each K in ``HARMONICS``, the sum of the periodogram at f0,
2f0, … Kf0 *less its largest term*: a single sinusoid, at any of those
frequencies, adds nothing to it, so the test needs at least two harmonics of
one fundamental — a shape, not a line. Its per-trial p-value is the tail of
the sum of K Exp(1) less the largest (simulated once per K, with its exact
exponential asymptote beyond the draws; the Gamma(K − 1) tail, an upper bound,
let 0 of 20,000 fresh null draws through at α 0.25 %: power thrown away). The statistic is the smallest p over the trials; its
family-wise ``ALPHA_COMB`` point comes from the same simulated effect-free
residuals as the window scan's (localized.projected_draws), extrapolated the
same way (localized.family_threshold).

When it fires the result is ``unexplained``; ``where`` gives the period, how
many harmonics, and the binned residual folded at that period: the share of the
period its peak occupies, so a pulse train is told from a smoother periodic
shape. A named periodic_interference at a multiple of the fundamental (or its
alias in the bins) has its probability multiplied by the probability that the
comb is noise; other named deterministic effects that add nothing beside the
comb's harmonics likewise (localized.judged_beside), and so does a named markov_bias: it is in the
noise model the comb judges by, so the comb is what that process does not make (20-s pulses
every 400 s on the 1-h P1 profile were named markov_bias at 0.99 beside a firing comb).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.localized import family_threshold, judged_beside, projected_draws
from gyrocal.analysis.discrepancy.lookalikes import TailVerdict
from gyrocal.analysis.discrepancy.result import DiscrepancyResult, FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit
from gyrocal.analysis.discrepancy.segments import Bins
from gyrocal.analysis.discrepancy.stochastic import MARKOV

#: Family-wise false-alarm rate this test may add (0.25 % first; at that level a true 10σ markov_bias on
#: the 1-h P1 profile, seed 26, drew a comb at 10^-6.5 against 10^-6.4 and lost its claim: lowered to 0.1 %).
ALPHA_COMB = 0.001
#: Harmonics summed (each less its largest term).
HARMONICS = (3, 6, 12)
#: Zero-padding of the periodogram: a harmonic off the Fourier grid is read within 1/(2·PAD) bin.
PAD = 4
#: A named line belongs to the comb when its frequency is within this share of a multiple of it.
LINE_TOLERANCE = 0.01
#: Simulated draws of the trimmed sum's null law per K, the draws beyond which its exponential
#: asymptote takes over, and their seed.
TAIL_DRAWS = 200_000
TAIL_KEEP = 40
TAIL_SEED = 2933
#: The folded residual's phase bins at most.
MAX_PHASES = 32


@dataclass(frozen=True)
class Comb(TailVerdict):
    """The comb test's outcome."""

    statistic: float        # −log10 of the smallest trial p
    threshold: float        # −log10 of its family-wise ALPHA_COMB point
    period_s: float = 0.0
    harmonics: int = 0
    shape: str = ""
    columns: np.ndarray | None = None   # the comb's harmonics (cos, sin) on the bins

    def describe(self) -> str:
        return (f"a periodic waveform that is not a sinusoid, period {self.period_s:.4g} s ({self.harmonics} "
                f"harmonics of one fundamental; harmonic comb of the final residual): {self.shape}")

    @property
    def note(self) -> str:
        verdict = self.describe() if self.fires else "no periodic non-sinusoidal waveform beyond the noise model"
        return (f"{verdict}: smallest comb p 10^-{self.statistic:.1f}, family-wise threshold "
                f"10^-{self.threshold:.1f} (harmonic_comb.py)")


def _periodogram(white: np.ndarray, m: int) -> np.ndarray:
    """|FFT|²/n of each column, zero-padded to ``m`` points (Exp(1) for unit white noise)."""
    return np.abs(np.fft.rfft(white, m, axis=0)) ** 2 / white.shape[0]


def _trials(n: int, k: int) -> np.ndarray:
    """Trial fundamentals (in padded-grid units) for ``k`` harmonics: from two periods in the record
    to where the k-th harmonic is at the bins' Nyquist, stepped so the k-th moves by ≤ 1/PAD bin."""
    lo, hi = 2.0 * PAD, n * PAD / (2.0 * k)
    if hi <= lo:
        return np.zeros(0)
    return np.arange(lo, hi, 1.0 / k)


def _comb_sums(power: np.ndarray, f0: np.ndarray, k: int) -> np.ndarray:
    """Σ of the periodogram at the first ``k`` harmonics of each trial, less the largest (trials × columns)."""
    total = np.zeros((f0.size, *power.shape[1:]))
    top = np.zeros_like(total)
    for h in range(1, k + 1):
        value = power[np.rint(h * f0).astype(int)]
        total += value
        np.maximum(top, value, out=top)
    return total - top


@functools.cache
def _trimmed_null(k: int) -> np.ndarray:
    """Sorted draws of the sum of K Exp(1) less the largest (their own generator; a function of K alone)."""
    draws = np.random.default_rng(TAIL_SEED + k).exponential(size=(TAIL_DRAWS, k))
    return np.sort(draws.sum(axis=1) - draws.max(axis=1))


def trimmed_score(x: np.ndarray, k: int) -> np.ndarray:
    """−log10 P(sum of K Exp(1) less the largest > x): the simulated tail, and beyond its last
    ``TAIL_KEEP`` draws the exact asymptote's slope, e^(−λx) with λ = K/(K − 1) (by Rényi's
    representation the sum is Σ Y_j (K − j)/(K − j + 1), j < K, so the slowest rate dominates)."""
    table = _trimmed_null(k)
    x = np.asarray(x, dtype=float)
    above = table.size - np.searchsorted(table, x, side="right")
    edge = table[table.size - TAIL_KEEP]
    inside = -np.log10(np.maximum(above, 1) / table.size)
    beyond = -math.log10(TAIL_KEEP / table.size) + (k / (k - 1.0)) * np.maximum(x - edge, 0.0) / math.log(10.0)
    return np.where(x <= edge, inside, beyond)


def _scores(power: np.ndarray, n: int) -> tuple[np.ndarray, tuple[int, int]]:
    """−log10 p of the best trial of each column, and (K, trial index) of the first column's best."""
    best = np.zeros(power.shape[1])
    first, top = (0, 0), -1.0
    for k in HARMONICS:
        f0 = _trials(n, k)
        if f0.size == 0:
            continue
        sums = _comb_sums(power, f0, k)
        i = np.argmax(sums, axis=0)
        score = trimmed_score(sums[i, np.arange(sums.shape[1])], k)
        if score[0] > top:
            top, first = float(score[0]), (k, int(i[0]))
        best = np.maximum(best, score)
    return best, first


def comb_threshold(null_white: np.ndarray, n_tests: int) -> float:
    """−log10 of the family-wise ALPHA_COMB point of the best trial, from whitened effect-free residuals."""
    null_score, _ = _scores(_periodogram(null_white, PAD * null_white.shape[0]), null_white.shape[0])
    return family_threshold(null_score, lambda x: 10.0 ** -x, n_tests, ALPHA_COMB)


def n_trials(n_bins: int) -> int:
    return sum(_trials(n_bins, k).size for k in HARMONICS)


def comb(white_resid: np.ndarray, resid_bins: np.ndarray, basis: np.ndarray, bins: Bins) -> Comb:
    """The comb test of a whitened binned residual (see the module docstring)."""
    n = white_resid.size
    m = PAD * n
    n_tests = n_trials(n)
    if n_tests == 0:
        return Comb(0.0, math.inf)
    data_score, (k, i) = _scores(_periodogram(white_resid[:, None], m), n)
    threshold = comb_threshold(projected_draws(n, basis), n_tests)
    statistic = float(data_score[0])
    if statistic <= threshold:
        return Comb(statistic, threshold)
    f0_cycles_per_bin = float(_trials(n, k)[i]) / m
    period_s = bins.width_s / f0_cycles_per_bin
    t = bins.centre_s
    cols = np.column_stack([f(2.0 * math.pi * h * t / period_s) for h in range(1, k + 1) for f in (np.cos, np.sin)])
    return Comb(statistic, threshold, period_s, k, folded(resid_bins, t, period_s, bins.width_s), cols)


def folded(resid_bins: np.ndarray, t_s: np.ndarray, period_s: float, width_s: float) -> str:
    """The residual folded at the period: where in the cycle it peaks, and over what share of it."""
    phases = int(max(4, min(MAX_PHASES, round(period_s / width_s))))
    index = np.floor((t_s % period_s) / period_s * phases).astype(int) % phases
    count = np.bincount(index, minlength=phases)
    profile = np.bincount(index, weights=resid_bins - resid_bins.mean(), minlength=phases) / np.maximum(count, 1)
    peak = int(np.argmax(np.abs(profile)))
    share = float(np.mean(np.abs(profile) >= 0.5 * abs(profile[peak])))
    kind = "a pulse train" if share <= 0.3 else "a periodic shape spread over the cycle"
    return (f"folded, it peaks at {profile[peak]:+.3g} deg/h {peak / phases * period_s:.0f} s into the cycle "
            f"and is above half its peak over {100 * share:.0f} % of the period ({kind})")


def comb_test(ctx: Context, after: Fit) -> Comb:
    return comb(after.white_resid, after.resid_bins, after.basis, ctx.bins)


def with_comb(ctx: Context, after: Fit, result: DiscrepancyResult) -> DiscrepancyResult:
    """The result once the comb test has run: fired, ``unexplained`` with the waveform in ``where``."""
    found = comb_test(ctx, after)
    notes = [*result.notes, found.note]
    if not found.fires:
        return replace(result, notes=notes)
    named = judged_beside(ctx, after, [_line_judged(f, found, ctx.bins.width_s) for f in result.found],
                          found.columns, found.whole_account)
    # a named Markov bias is in the noise model the comb judges by: the comb is what it does not make
    named = [replace(f, probability=f.probability * found.whole_account) if f.name == MARKOV else f for f in named]
    # after what the sharper tests said (an angle-locked line, spikes): the comb may be their echo
    where = f"{result.where}; {found.describe()}" if result.where else found.describe()
    return replace(result, found=named, unexplained=True, where=where, notes=notes)


def _line_judged(effect: FoundEffect, found: Comb, width_s: float) -> FoundEffect:
    """A named line at a multiple of the comb's fundamental (or aliased onto one in the bins) is one of its
    harmonics: its probability falls by the comb's odds."""
    if effect.name != "periodic_interference" or "freq_hz" not in effect.parameters:
        return effect
    f0, fs_bins = 1.0 / found.period_s, 1.0 / width_s
    f = float(effect.parameters["freq_hz"]) % fs_bins
    for candidate in (f, fs_bins - f, float(effect.parameters["freq_hz"])):
        ratio = candidate / f0
        if ratio >= 0.5 and abs(ratio - round(ratio)) <= LINE_TOLERANCE * max(round(ratio), 1):
            return replace(effect, probability=effect.probability * found.whole_account)
    return effect
