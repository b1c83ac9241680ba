"""Localized bias structure left in the final residual: a multi-scale scan of window means (issue 29).

Every other test of what the named effects leave reads a shape that spans the
record (the probes: steps, polynomials, sinusoids, terms in temperature and
rate), a spectrum, a scatter or single samples. Structure that lives in a few
short stretches of the record — a few bias steps of random sign (mode hops), a
bump, a short burst, a plateau between two steps — matches none of them well;
on the fifth held-out set mode hops were named bias_temp_quadratic at ≥ 0.8 and
nothing said that something local was left.

What is measured. The mean of the final refit's binned residual over windows
of every dyadic width from one bin to a quarter of the record
(``MAX_SHARE``), at positions a quarter of a width apart: each window's sum S
divided by its standard deviation under the *fitted* noise model after the
refit, ``Var S = aᵀ C a − ‖(L Q)ᵀ a‖²`` (C = L·Lᵀ the bin-mean covariance the
workflow whitens with, Q the orthonormal basis of the whitened fitted columns,
a the window's indicator). Flicker and random walk make long windows noisier:
the normalisation is that model's, not white noise's, so a window's z² is
exactly χ²₁ under the null whatever the noise. The window sums and variances
come from prefix sums (of r, of C in two dimensions, of L·Q), so the ~8n
windows cost O(n²) once.

The threshold. The statistic is the largest z² over all windows and widths.
Its family-wise (1 − ``ALPHA_LOCALIZED``) point is calibrated on ``N_NULL_DRAWS``
simulated effect-free residuals of the same noise model and refit
(``L (I − Q Qᵀ) z``, z standard normal, as the gap pass draws its null
residuals), with the draws' own generator so the workflow's shared one is left
as it was. ``N_NULL_DRAWS`` is too few to read a 0.5 % point directly: the
draws give the effective number of independent windows M at their 50 % and 90 %
points, and the tail is ``P(max > x) = 1 − (1 − p₁(x))^M(x)`` with M growing as a
power of x between them (a smooth field has more upcrossings the higher the
level), extrapolated to ``ALPHA_LOCALIZED``.

When it fires the result is ``unexplained`` and ``where`` lists the strongest
non-overlapping windows (time span, mean shift in deg/h, z at that scale). A
named deterministic effect that adds nothing significant once those windows
are fitted beside the rest has its probability multiplied by the probability
that the residual is the noise model's (the claim odds rule), as adequacy.py
does for a probe.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize, stats

from gyrocal.analysis.discrepancy.adequacy import NOT_JUDGED
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import TailVerdict
from gyrocal.analysis.discrepancy.result import DiscrepancyResult, FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit, Whitener, score_from_delta
from gyrocal.analysis.discrepancy.segments import Bins
from gyrocal.analysis.discrepancy.signatures import effect_columns
from gyrocal.analysis.discrepancy.stochastic import MARKOV

#: Family-wise false-alarm rate this test may add (half of the 0.5 % budget; harmonic_comb.py has the other).
ALPHA_LOCALIZED = 0.0025
#: The widest window, as a share of the record (wider is a step or a slow shape: the probes' job).
MAX_SHARE = 0.25
#: Simulated effect-free residuals the threshold is calibrated on (their own generator).
N_NULL_DRAWS = 200
NULL_SEED = 2931
#: Windows listed in ``where`` at most.
MAX_LISTED = 4


@dataclass(frozen=True)
class Windows:
    """Every window scanned: first bin, one past the last, and the null variance of its sum."""

    start: np.ndarray
    stop: np.ndarray
    variance: np.ndarray


@dataclass(frozen=True)
class Localized(TailVerdict):
    """The scan's outcome on one record."""

    statistic: float          # −log10 χ²₁ tail p of the largest window z²
    threshold: float          # −log10 of its family-wise ALPHA_LOCALIZED point
    #: (from s, to s, mean deg/h, z, whether in the innovations) of each window listed
    spans_s: tuple[tuple[float, float, float, float, bool], ...] = ()
    columns: np.ndarray | None = None   # the listed windows' indicators on the bins

    def describe(self) -> str:
        parts = [f"{'innovations (a jump the fitted noise process does not make)' if innov else 'a mean shift'}"
                 f" of {m:+.3g} deg/h over t = {a:.0f}–{b:.0f} s ({z:.1f}σ by the noise model at that scale)"
                 for a, b, m, z, innov in self.spans_s]
        return ("localized bias structure the named effects leave (window scan of the final residual): "
                + "; ".join(parts))

    @property
    def note(self) -> str:
        verdict = self.describe() if self.fires else "no localized bias structure beyond the noise model"
        return (f"{verdict}: largest window p 10^-{self.statistic:.1f}, family-wise threshold "
                f"10^-{self.threshold:.1f} (localized.py)")


def windows(n_bins: int, cov: np.ndarray | None, fitted: np.ndarray) -> Windows:
    """Dyadic windows and the variance of each one's residual sum under the noise model and refit.

    ``fitted`` is L·Q (the whitened fitted basis coloured back): the refit removes
    its span from the noise, so Var S = aᵀCa − ‖(LQ)ᵀa‖². ``cov`` None: the
    whitened residual's windows (C = I, ``fitted`` = Q).
    """
    starts, stops = [], []
    width = 1
    while width <= max(1, int(MAX_SHARE * n_bins)):
        s = np.arange(0, n_bins - width + 1, max(1, width // 4))
        starts.append(s)
        stops.append(s + width)
        width *= 2
    start, stop = np.concatenate(starts), np.concatenate(stops)
    if cov is None:
        box = (stop - start).astype(float)
    else:
        prefix = np.zeros((n_bins + 1, n_bins + 1))
        prefix[1:, 1:] = np.cumsum(np.cumsum(cov, axis=0), axis=1)
        box = prefix[stop, stop] - prefix[start, stop] - prefix[stop, start] + prefix[start, start]
    cum = np.zeros((n_bins + 1, fitted.shape[1]))
    cum[1:] = np.cumsum(fitted, axis=0)
    removed = np.sum((cum[stop] - cum[start]) ** 2, axis=1)
    return Windows(start, stop, np.maximum(box - removed, 1e-12 * np.maximum(box, 1e-300)))


def window_z2(resid: np.ndarray, w: Windows) -> np.ndarray:
    """z² of every window's sum (rows) for one residual or each column of several."""
    cum = np.zeros((resid.shape[0] + 1, *resid.shape[1:]))
    cum[1:] = np.cumsum(resid, axis=0)
    sums = cum[w.stop] - cum[w.start]
    var = w.variance if resid.ndim == 1 else w.variance[:, None]
    return sums * sums / var


def projected_draws(n_bins: int, basis: np.ndarray, draws: int = N_NULL_DRAWS) -> np.ndarray:
    """Whitened effect-free residuals of the refit, ``(I − Q Qᵀ) z``, from this module's own generator."""
    z = np.random.default_rng(NULL_SEED).standard_normal((n_bins, draws))
    return z - basis @ (basis.T @ z)


def family_threshold(null_max: np.ndarray, tail: Callable[[float], float], n_tests: int, alpha: float) -> float:
    """The ``alpha`` point of a maximum over many tests, extrapolated from simulated draws of it.

    ``tail(x)`` is one test's null tail probability. M(x), the effective number of
    independent tests at level x, is read at the draws' 50 % and 90 % points
    (1 − (1 − tail(x))^M = the level) and taken to grow as a power of x between and
    beyond them (at most ``n_tests``); the threshold solves 1 − (1 − tail(x))^M(x) = alpha.
    """
    levels = (0.5, 0.9)
    xs = [float(np.quantile(null_max, lv)) for lv in levels]
    ms = [math.log1p(-lv) / math.log1p(-min(tail(x), 1.0 - 1e-12)) for x, lv in zip(xs, levels, strict=True)]
    beta = max(0.0, math.log(ms[1] / ms[0]) / math.log(xs[1] / xs[0])) if xs[1] > xs[0] > 0 else 0.0

    def excess(x: float) -> float:
        m = min(ms[1] * (x / xs[1]) ** beta, float(n_tests))
        return -math.expm1(m * math.log1p(-min(tail(x), 1.0 - 1e-12))) - alpha

    lo, hi = xs[0], max(xs[1], 1e-9)
    if excess(lo) <= 0:
        return lo
    while excess(hi) > 0:
        hi *= 1.5
    return float(optimize.brentq(excess, lo, hi))


def scan(resid_bins: np.ndarray, white_resid: np.ndarray, whitener: Whitener, basis: np.ndarray,
         bins: Bins) -> Localized:
    """The scan of a refit's binned residual and its innovations (whitened residual), one family."""
    n, chol = resid_bins.size, whitener.chol
    rate = windows(n, whitener.covariance, chol @ basis)
    innov = windows(n, None, basis)
    z2 = np.concatenate([window_z2(resid_bins, rate), window_z2(white_resid, innov)])
    null = projected_draws(n, basis)
    null_max = np.maximum(window_z2(chol @ null, rate).max(axis=0), window_z2(null, innov).max(axis=0))
    x_alpha = family_threshold(null_max, _chi2_1_tail, z2.size, ALPHA_LOCALIZED)
    statistic, threshold = score_from_delta(float(z2.max()), 1), score_from_delta(x_alpha, 1)
    if statistic <= threshold:
        return Localized(statistic, threshold)
    both = Windows(np.concatenate([rate.start, innov.start]), np.concatenate([rate.stop, innov.stop]),
                   np.concatenate([rate.variance, innov.variance]))
    chosen = sorted(_strongest_apart(z2, both, x_alpha), key=lambda k: both.start[k])
    cols, spans, half = np.zeros((n, len(chosen))), [], 0.5 * bins.width_s
    for j, i in enumerate(chosen):
        a, b = int(both.start[i]), int(both.stop[i])
        cols[a:b, j] = 1.0
        if i >= rate.start.size:   # a box of the innovations is the coloured box in the bins
            cols[:, j] = chol @ cols[:, j]
        spans.append((float(bins.centre_s[a] - half), float(bins.centre_s[b - 1] + half),
                      float(resid_bins[a:b].mean()), float(math.sqrt(z2[i])), i >= rate.start.size))
    return Localized(statistic, threshold, tuple(spans), cols)


def _chi2_1_tail(x: float) -> float:
    return float(stats.chi2.sf(x, 1))


def _strongest_apart(z2: np.ndarray, w: Windows, level: float) -> list[int]:
    """The strongest windows above ``level`` that do not overlap, strongest first (at most MAX_LISTED)."""
    chosen: list[int] = []
    for i in np.argsort(z2)[::-1]:
        if z2[i] <= level or len(chosen) >= MAX_LISTED:
            break
        if all(w.stop[i] <= w.start[k] or w.start[i] >= w.stop[k] for k in chosen):
            chosen.append(int(i))
    return chosen


def localized_test(ctx: Context, after: Fit) -> Localized:
    """The scan of the final refit's binned residual (see the module docstring)."""
    return scan(after.resid_bins, after.white_resid, ctx.whitener, after.basis, ctx.bins)


def with_localized(ctx: Context, after: Fit, result: DiscrepancyResult) -> DiscrepancyResult:
    """The workflow's result once the window scan has run: fired, ``unexplained`` with the windows in ``where``.

    A named markov_bias is in the noise model the scan judges by, so what the scan finds is
    what that process does not make: its claim takes the scan's odds too (three random bias
    steps on the 1-h P1 profile were named markov_bias at 1.00 with the steps left over).
    """
    found = localized_test(ctx, after)
    notes = [*result.notes, found.note]
    if not found.fires:
        return replace(result, notes=notes)
    # after what the sharper tests said (an angle-locked line, spikes): the windows may be their echo
    where = f"{result.where}; {found.describe()}" if result.where else found.describe()
    named = [replace(f, probability=f.probability * found.whole_account) if f.name == MARKOV else f
             for f in judged_beside(ctx, after, result.found, found.columns, found.whole_account)]
    return replace(result, found=named, unexplained=True, where=where, notes=notes)


def judged_beside(ctx: Context, after: Fit, found: list[FoundEffect], columns: np.ndarray | None,
                  whole_account: float) -> list[FoundEffect]:
    """Named deterministic effects that add nothing significant beside ``columns`` (binned shapes of what
    was found) have their probability multiplied by ``whole_account``, as adequacy.judged does."""
    if columns is None or all(f.name in NOT_JUDGED for f in found):
        return found
    white = ctx.whitener.white(columns)
    out = []
    for f in found:
        if f.name not in NOT_JUDGED:
            without = ctx.fit(after.model.without_effect(f.name))
            gain = (without.chi2 - _gain(white, without)) - (after.chi2 - _gain(white, after))
            if score_from_delta(gain, max(len(effect_columns(f.name)), 1)) <= f.threshold:
                f = replace(f, probability=f.probability * whole_account)
        out.append(f)
    return out


def _gain(white_columns: np.ndarray, fit: Fit) -> float:
    """Δχ² of the windows' columns added to ``fit``."""
    perp = white_columns - fit.basis @ (fit.basis.T @ white_columns)
    q, r = np.linalg.qr(perp)
    good = np.abs(np.diag(r)) > 1e-7 * max(float(np.abs(np.diag(r)).max()), 1e-300)
    proj = q[:, good].T @ fit.white_resid
    return float(proj @ proj)
