"""Single-sample outliers and spikes in the final refit's full-rate residual (issue 29).

Every other test reads bin means, a spectrum or a within-window scatter that
clips spikes (noise_level.py clips at 5 robust σ on purpose, so a spike cannot
pose as a noise level). On the third held-out set "five single-sample outliers
(Laplace values)" and "one sample's angle counted twice every 7.3 s (spikes ∝ ω)"
came out with no claim and not ``unexplained`` on every profile: nothing looked
at the tails of the samples.

What is measured. Each sample's departure from its neighbours,
``D_k = r_k − (L_k + R_k)/2`` with ``L_k``, ``R_k`` the means of the
``SIDE_SAMPLES`` samples on either side: a linear filter, so under the fitted
noise model (white rate noise, white angle noise, slow processes) D is
Gaussian, and anything slower than a few samples (a missing catalogue effect,
the Markov bias, a slew's smooth residual, a ramp) cancels. A sample counts as a
*spike* only when it stands out from both sides alike (``r_k − L_k`` and
``r_k − R_k`` of one sign, each at least half of ``D_k``) and its neighbours do
not (each ``|D_(k±1)|`` below ``NEIGHBOUR_SHARE`` of ``|D_k|``): a step (dead_zone
at a slew, a block of zeroed samples) or a two-sample block is not a spike.
``D`` is standardized by its own scale per window of ``WINDOW_SAMPLES``
(clipped RMS, so the spikes do not set it), and the per-sample null law is
Student's t with the window's degrees of freedom (the scale is estimated).

The test. Three −log10 p-values on one record: the largest |z| (extreme value,
``P = 1 − exp(−n·p(z))``), and the count of spikes beyond ``COUNT_LEVELS``
(3.5 and 4.5) against Poisson(n·p(level)). The first sees a few large outliers,
the counts many moderate ones (a doubled sample every few seconds). The
statistic is the smallest p; its threshold is the ``ALPHA_OUTLIERS`` point of
the same smallest p on ``N_NULL_DRAWS`` simulated effect-free records (the
null exceedance process: a Poisson count above the lower level, its values
drawn from the tail law), so the three tests' dependence is accounted for, as
adequacy.family_threshold does for the probes. ``ALPHA_OUTLIERS`` = 0.5 %: the
budget this test may add to the family-wise false alarms.

Non-Gaussian noise the model has on purpose (a pulse counter's quantization,
an output LSB) is bounded: its tails are lighter than the Gaussian's, so it can
only make the test conservative.

When it fires the result is ``unexplained`` and ``where`` says how many spikes,
how large, whether their sizes follow |rate| (and their sign the rate's), and
when (a period when they are regular). A named deterministic effect that no
longer adds significantly once the spikes are taken out has its probability
multiplied by ``whole_account`` (the claim odds rule), as adequacy.py does for
a probe.

Measured (``benchmarks/validate_outliers.py``, the test on the base refit of
simulated logs; docs/discrepancy-validation.md, "Single-sample outliers and
spikes"): effect-free controls fired 1 of 400 on P1, Q1–Q3 (a lone 5.4σ sample
on P1), and 8 of 2000 white-noise records of 135,000 samples (0.40 %, α 0.5 %).
Own cases (tests/support/outlier_cases.py) found in 50 of 50 per profile: 3–8
outliers of 8–30σ (heavy-tailed sizes), a sample counted twice every 4.1 s while
turning (whole, or sized to 10σ at the top rate); 5–10σ outliers 49–50 of 50, 6σ
doubled samples 49–50 of 50. Catalogue effects at 10σ left unmodelled leave it
quiet (0 of 20 each on P1 and Q2) except dead_zone, whose one-sample passes
through the dead band in a slew *are* single-sample spikes; named by the
workflow (it is, first, at 10σ) it leaves none: over 42 whole-workflow runs of
seven catalogue effects on P1 and Q2 the test fired on none and every result is
the same with and without it. CPU: 0.005 s on P1, 0.01 s on Q1–Q3, 0.023 s on
930,000 samples (P2-sized), 0.18–0.29 s on 10 M samples (loaded machine; the two
per-sample passes compiled, their array versions 0.07 s and 1.2 s).

What it cannot see: spikes each small beside the noise (a norm of 10σ spread
over hundreds of samples is under 1σ a spike); only a test that knew their
period or their ∝ω shape could add them up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from gyrocal.analysis.discrepancy.adequacy import NOT_JUDGED
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.result import DiscrepancyResult, FoundEffect
from gyrocal.analysis.discrepancy.scoring import (
    Fit,
    gls_fit,
    order_statistic_quantile,
    score_from_delta,
)
from gyrocal.analysis.discrepancy.signatures import effect_columns

#: Family-wise false-alarm rate this test may add.
ALPHA_OUTLIERS = 0.005
#: Samples on each side whose mean is a sample's local level.
SIDE_SAMPLES = 4
#: Samples per window of the scale estimate (a shorter tail is merged into the last window).
WINDOW_SAMPLES = 4096
#: Spike counts are compared with their null expectation beyond these |z| levels.
COUNT_LEVELS = (3.5, 4.5)
#: A spike's neighbours stand out by less than this share of it.
NEIGHBOUR_SHARE = 0.75
#: Clip of the scale estimate, in first-pass robust standard deviations.
CLIP_SIGMA = 5.0
#: Simulated effect-free exceedance processes for the threshold.
N_NULL_DRAWS = 20000
#: Seed of the null draws (their own generator, see ``_null_threshold``).
NULL_SEED = 2929
#: Spikes listed by time in ``where`` when they are few and irregular.
MAX_LISTED = 5
#: Spikes needed, and the rank correlation's p-value, to say their sizes follow |rate|.
MIN_FOR_RATE_LAW = 6
RATE_LAW_P = 0.001
#: Smallest gaps tried as the period of a regular spike train.
PERIOD_CANDIDATES = 30


@dataclass(frozen=True)
class Spikes:
    """The spike test's outcome."""

    statistic: float          # −log10 of the smallest of the three p-values
    threshold: float          # −log10 of its ALPHA_OUTLIERS point on simulated null records
    samples: int              # samples judged
    index: np.ndarray         # the spikes described (sample indices)
    size_dph: np.ndarray      # their departures D_k, deg/h
    z: np.ndarray             # their |z|
    level: float              # |z| beyond which they are listed
    expected: float           # spikes expected beyond ``level`` under the noise model
    description: str = ""

    @property
    def fires(self) -> bool:
        return self.statistic > self.threshold

    @property
    def note(self) -> str:
        verdict = self.description if self.fires else "no single-sample spikes beyond the noise model"
        return (f"{verdict}: smallest tail p 10^-{self.statistic:.1f} over {self.samples:,} samples, "
                f"threshold 10^-{self.threshold:.1f} (outliers.py)")

    @property
    def whole_account(self) -> float:
        """Probability that the tails are the noise model's: the claim odds rule on −log10 p."""
        return 1.0 - real_probability(self.statistic, self.threshold) if self.fires else 1.0


def spike_test(ctx: Context, after: Fit) -> Spikes:
    """The test on the refitted model's full-rate residual (see the module docstring)."""
    return spikes_in(ctx.resid_full(after), ctx.log.t_s, ctx.log.table_rate_dps, ctx.fs_hz)


def spikes_in(resid_dph: np.ndarray, t_s: np.ndarray, rate_dps: np.ndarray, fs_hz: float) -> Spikes:
    """The test on a full-rate residual (deg/h) with its times and table rates."""
    d, spike = departures(resid_dph)
    az, n, nu_eff = scaled(d, spike)
    if n < 100:
        return Spikes(0.0, math.inf, n, np.zeros(0, int), np.zeros(0), np.zeros(0), math.inf, 0.0)
    counts = [int(np.count_nonzero(az > c)) for c in COUNT_LEVELS]
    logp, which = _log10_pvalues(float(az.max()), counts, n, nu_eff)
    level = _max_level(n, nu_eff) if which == 0 else COUNT_LEVELS[which - 1]
    idx = np.flatnonzero(az > level)
    out = Spikes(-logp, _null_threshold(n, nu_eff), n, idx, d[idx], az[idx], level,
                 n * float(_two_sided_sf(level, nu_eff)))
    return replace(out, description=describe(out, t_s, rate_dps, fs_hz))


def departures(resid: np.ndarray, compiled: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's departure D from the mean level of its two sides, and whether it is spike-shaped.

    ``compiled``: the one-pass loop (numba) when it is there, else the array version, its oracle.
    """
    r = np.ascontiguousarray(resid, dtype=np.float64)
    d = np.zeros(r.size)
    spike = np.zeros(r.size, dtype=np.bool_)
    if r.size < 2 * SIDE_SAMPLES + 3:
        return d, spike
    if compiled and _departures_loop is not None:
        _departures_loop(r, SIDE_SAMPLES, NEIGHBOUR_SHARE, d, spike)
    else:
        _departures_numpy(r, d, spike)
    return d, spike


def _departures_numpy(r: np.ndarray, d: np.ndarray, spike: np.ndarray) -> None:
    n, w = r.size, SIDE_SAMPLES
    c = np.empty(n + 1)
    c[0] = 0.0
    np.cumsum(r - r[0], out=c[1:])        # less the first sample: the sums stay small
    body = slice(w, n - w)
    a = r[body] - r[0] - (c[w:n - w] - c[: n - 2 * w]) / w               # less the left mean
    b = r[body] - r[0] - (c[2 * w + 1:] - c[w + 1: n - w + 1]) / w        # less the right mean
    d[body] = 0.5 * (a + b)
    half = 0.5 * np.abs(d[body])
    ok = (a * b > 0) & (np.abs(a) >= half) & (np.abs(b) >= half)
    # neighbours below NEIGHBOUR_SHARE of it: |D| = 2·half
    bound = 2.0 * NEIGHBOUR_SHARE * half
    ok &= np.abs(d[w - 1: n - w - 1]) < bound
    ok &= np.abs(d[w + 1: n - w + 1]) < bound
    spike[body] = ok


def scaled(d: np.ndarray, spike: np.ndarray, compiled: bool = True) -> tuple[np.ndarray, int, float]:
    """|D| over its window's clipped RMS at the spikes (0 elsewhere), the samples judged, the median ν.

    The first clip only needs to be generous: (CLIP_SIGMA + 1) robust σ from a median of
    every 7th sample. Each window then clips at CLIP_SIGMA of its own first-pass RMS, so the
    spikes do not set the scale.
    """
    valid = d[::7] != 0.0
    some = np.abs(d[::7][valid])
    clip0 = (CLIP_SIGMA + 1.0) * 1.4826 * float(np.median(some)) if some.size else 0.0
    nwin = max(d.size // WINDOW_SAMPLES, 1)
    az, count = np.zeros(d.size), np.zeros(nwin)
    if compiled and _scaled_loop is not None:
        _scaled_loop(d, spike, WINDOW_SAMPLES, clip0, CLIP_SIGMA, _TRUNCATED_VARIANCE, az, count)
    else:
        _scaled_numpy(d, spike, clip0, az, count)
    ok = count > 10
    judged = int(count[ok].sum())
    return az, judged, float(np.median(count[ok] - 1.0)) if np.any(ok) else 0.0


def _scaled_numpy(d: np.ndarray, spike: np.ndarray, clip0: float, az: np.ndarray, count: np.ndarray) -> None:
    n, nwin = d.size, count.size
    valid, ad = d != 0.0, np.abs(d)
    clip = np.full(nwin, clip0)
    for _ in range(2):
        keep = valid & (ad < _per_sample(clip, n))
        count[:] = _window_sums(keep.astype(float), nwin)
        ss = _window_sums(np.where(keep, d * d, 0.0), nwin)
        scale = np.sqrt(ss / np.maximum(count, 1.0) / _TRUNCATED_VARIANCE)
        clip = CLIP_SIGMA * scale
    count[:] = _window_sums(valid.astype(float), nwin) * ((count > 10) & (scale > 0))
    ok = count > 10
    az[:] = np.where(spike & _per_sample(ok, n), ad / _per_sample(np.where(ok, scale, 1.0), n), 0.0)


def _window_sums(x: np.ndarray, nwin: int) -> np.ndarray:
    """Sums over windows of WINDOW_SAMPLES (the tail after the last whole window joins it)."""
    whole = min(nwin * WINDOW_SAMPLES, x.size)
    sums = x[:whole].reshape(nwin, -1).sum(axis=1)
    sums[-1] += x[whole:].sum()
    return sums


def _per_sample(per_window: np.ndarray, n: int) -> np.ndarray:
    """Window values back on the samples (the tail takes the last window's)."""
    out = np.repeat(per_window, WINDOW_SAMPLES)[:n]
    if out.size < n:
        out = np.concatenate([out, np.full(n - out.size, per_window[-1])])
    return out


try:  # numba is a declared dependency; the fallback keeps the test alive if it breaks
    import numba

    @numba.njit(cache=True, nogil=True)
    def _departures_loop(r, w, share, d, spike):  # pragma: no cover
        # _departures_numpy in one pass: running sums of the w samples either side
        n, r0 = r.size, r[0]
        left, right = 0.0, 0.0
        for i in range(w):
            left += r[i] - r0
            right += r[w + 1 + i] - r0
        for k in range(w, n - w):
            if k > w:
                left += r[k - 1] - r[k - 1 - w]
                right += r[k + w] - r[k]
            a = r[k] - r0 - left / w
            b = r[k] - r0 - right / w
            d[k] = 0.5 * (a + b)
            half = 0.5 * abs(d[k])
            spike[k] = a * b > 0 and abs(a) >= half and abs(b) >= half
        for k in range(w, n - w):
            if spike[k]:
                bound = share * abs(d[k])
                spike[k] = abs(d[k - 1]) < bound and abs(d[k + 1]) < bound

    @numba.njit(cache=True, nogil=True)
    def _scaled_loop(d, spike, window, clip0, clip_sigma, truncated, az, count):  # pragma: no cover
        # _scaled_numpy window by window: two clipped passes, then |z| at the spikes
        nwin = count.size
        for j in range(nwin):
            lo, hi = j * window, (j + 1) * window if j < nwin - 1 else d.size
            clip, scale, kept = clip0, 0.0, 0.0
            for _ in range(2):
                ss, kept = 0.0, 0.0
                for i in range(lo, hi):
                    if d[i] != 0.0 and abs(d[i]) < clip:
                        ss += d[i] * d[i]
                        kept += 1.0
                scale = np.sqrt(ss / max(kept, 1.0) / truncated)
                clip = clip_sigma * scale
            if kept <= 10 or scale <= 0:
                continue
            valid = 0.0
            for i in range(lo, hi):
                if d[i] != 0.0:
                    valid += 1.0
                    if spike[i]:
                        az[i] = abs(d[i]) / scale
            count[j] = valid
except ImportError:  # pragma: no cover - exercised only where numba cannot be installed
    _departures_loop = None
    _scaled_loop = None


#: Variance of a standard normal truncated at ±CLIP_SIGMA (the clipped RMS's consistency factor).
_TRUNCATED_VARIANCE = 1.0 - 2.0 * CLIP_SIGMA * stats.norm.pdf(CLIP_SIGMA) / (1.0 - 2.0 * stats.norm.sf(CLIP_SIGMA))


def _two_sided_sf(z: float | np.ndarray, nu: float) -> float | np.ndarray:
    return 2.0 * stats.t.sf(z, nu)


def _log10_pvalues(zmax: float, counts: list[int], n: int, nu: float) -> tuple[float, int]:
    """log10 of the smallest p-value (max test, then the counts), and which one it was."""
    p_max = -math.expm1(-n * float(_two_sided_sf(zmax, nu)))
    logs = [math.log10(max(p_max, 1e-300))]
    for level, count in zip(COUNT_LEVELS, counts, strict=True):
        lam = n * float(_two_sided_sf(level, nu))
        logs.append(float(stats.poisson.logsf(count - 1, lam)) / math.log(10.0) if count > 0 else 0.0)
    which = int(np.argmin(logs))
    return logs[which], which


def _max_level(n: int, nu: float) -> float:
    """|z| a single sample must pass to be significant by itself at ALPHA_OUTLIERS."""
    return float(stats.t.isf(-math.log1p(-ALPHA_OUTLIERS) / n / 2.0, nu))


def _null_threshold(n: int, nu: float) -> float:
    """−log10 of the ALPHA_OUTLIERS point of the smallest p on simulated effect-free records.

    Under the noise model the samples beyond the lower count level form a Poisson
    process of rate n·p(level) whose |z| follow the tail law; a draw is the count,
    how many of them pass the higher level (binomial), and the largest (the
    smallest of k uniform tail probabilities is 1 − V^(1/k)). As exact as drawing
    n samples per record, and its cost does not grow with the record. The draws
    have their own seed: the threshold is a function of (n, ν) alone, and the
    workflow's shared generator is left to the tests after this one.
    """
    rng = np.random.default_rng(NULL_SEED)
    lo, hi = COUNT_LEVELS
    p_lo, p_hi = float(_two_sided_sf(lo, nu)), float(_two_sided_sf(hi, nu))
    n_lo = rng.poisson(n * p_lo, N_NULL_DRAWS)
    n_hi = rng.binomial(n_lo, p_hi / p_lo)
    v = rng.random(N_NULL_DRAWS)
    top = np.where(n_hi > 0, p_hi, p_lo)
    k = np.where(n_hi > 0, n_hi, n_lo)
    floor = np.where(n_hi > 0, 0.0, p_hi)
    tail = np.where(k > 0, floor + (top - floor) * -np.expm1(np.log(v) / np.maximum(k, 1)), p_lo)
    logs = np.vstack([np.log10(np.maximum(-np.expm1(-n * tail), 1e-300)),
                      stats.poisson.logsf(n_lo - 1, n * p_lo) / math.log(10.0),
                      stats.poisson.logsf(n_hi - 1, n * p_hi) / math.log(10.0)])
    logs[1:][np.vstack([n_lo, n_hi]) == 0] = 0.0
    return -order_statistic_quantile(np.min(logs, axis=0), ALPHA_OUTLIERS)


def describe(spikes: Spikes, t_s: np.ndarray, rate_dps: np.ndarray, fs_hz: float) -> str:
    """The spikes in plain words: how many, how large, against |rate|, when."""
    idx = spikes.index
    if idx.size == 0:
        return ""
    sigma = spikes.size_dph / np.where(spikes.z > 0, spikes.z, 1.0)
    sizes = spikes.z
    span = f"{sizes.min():.3g}–{sizes.max():.3g}" if idx.size > 1 else f"{sizes.max():.3g}"
    head = (f"{idx.size} single-sample spike{'s' if idx.size > 1 else ''} of {span}σ beyond the fitted "
            f"noise (expected {spikes.expected:.2g} beyond {spikes.level:.2g}σ; largest {np.max(np.abs(spikes.size_dph)):.3g} deg/h, σ "
            f"{float(np.median(np.abs(sigma))):.3g} deg/h)")
    parts = [head, _against_rate(spikes.size_dph, rate_dps[idx]),
             _when(t_s[idx] - float(t_s[0]), fs_hz)]
    return ", ".join(p for p in parts if p)


def _against_rate(size_dph: np.ndarray, rate_dps: np.ndarray) -> str:
    """Whether the sizes follow |rate| (rank correlation of |size| and |rate|) and the sign the rate's."""
    abs_rate = np.abs(rate_dps)
    moving = abs_rate > 1e-6
    if not np.any(moving):
        return "all at rest"
    count = int(np.count_nonzero(moving))
    text = f"{count} of {size_dph.size} while the table turns"
    if size_dph.size >= MIN_FOR_RATE_LAW:
        rho, p = stats.spearmanr(np.abs(size_dph), abs_rate)
        law = "∝ |rate|" if rho > 0 and p < RATE_LAW_P else "not ∝ |rate|"
        text = f"sizes {law} (rank r = {rho:.2f})"
    if count >= MIN_FOR_RATE_LAW:
        same = float(np.mean(np.sign(size_dph[moving]) == np.sign(rate_dps[moving])))
        if same >= 0.9 or same <= 0.1:
            text += f", sign {'with' if same >= 0.9 else 'against'} the rate"
    return text


def _when(t_s: np.ndarray, fs_hz: float) -> str:
    """The spikes' times: listed when few, a period when they are regular, else their span."""
    if t_s.size <= MAX_LISTED:
        return "at t = " + ", ".join(f"{t:.1f}" for t in t_s) + " s"
    period = _period(np.diff(t_s), fs_hz)
    if period:
        return f"every {period:.3g} s (or a multiple) from {t_s[0]:.0f} to {t_s[-1]:.0f} s"
    return f"from {t_s[0]:.0f} to {t_s[-1]:.0f} s"


def _period(gaps: np.ndarray, fs_hz: float) -> float:
    """The smallest gap of which ≥ 80 % of the gaps are whole multiples, else 0.

    A multiple is within max(1.5 samples, 2 %) of the gap, and a gap is tried only
    when that tolerance is under a quarter of it: a chance match of random times is
    then rare, so "every P s" is said only of a real train.
    """
    gaps = gaps[gaps > 0]
    for g in np.unique(np.round(gaps, 3))[:PERIOD_CANDIDATES]:
        if 1.5 / fs_hz > 0.25 * g:
            continue
        m = np.round(gaps / g)
        near = (m >= 1) & (np.abs(gaps - m * g) <= max(1.5 / fs_hz, 0.02 * g))
        if np.mean(near) >= 0.8:
            return float(gaps[near].sum() / m[near].sum())
    return 0.0


def with_spikes(ctx: Context, after: Fit, result: DiscrepancyResult) -> DiscrepancyResult:
    """The workflow's result once the spike test has run on the final refit.

    Fired: ``unexplained``, the spikes first in ``where`` (a comb of lines they make
    comes after), and the named effects they replace below their claim. Always: its note.
    """
    spikes = spike_test(ctx, after)
    notes = [*result.notes, spikes.note]
    if not spikes.fires:
        return replace(result, notes=notes)
    where = f"{spikes.description}; {result.where}" if result.where else spikes.description
    return replace(result, found=judged_by_spikes(ctx, after, result.found, spikes), unexplained=True,
                   where=where, notes=notes)


def judged_by_spikes(ctx: Context, after: Fit, found: list[FoundEffect], spikes: Spikes) -> list[FoundEffect]:
    """The named effects with the probabilities the spikes leave them.

    The spikes are taken out (each replaced by its local level) and every named
    deterministic effect refitted: one that no longer adds significantly (its own
    threshold) was the spikes' weight in a bin mean, and its probability is
    multiplied by ``spikes.whole_account``.
    """
    if not spikes.fires or all(f.name in NOT_JUDGED for f in found):
        return found
    y = ctx.y_full.copy()
    y[spikes.index] -= spikes.size_dph
    y_bins = ctx.bins.mean(y)
    with_all = gls_fit(ctx.builder, ctx.whitener, y_bins, after.model).chi2
    out = []
    for f in found:
        if f.name not in NOT_JUDGED:
            without = gls_fit(ctx.builder, ctx.whitener, y_bins, after.model.without_effect(f.name)).chi2
            dof = max(len(effect_columns(f.name)), 1)
            if score_from_delta(without - with_all, dof) <= f.threshold:
                f = replace(f, probability=f.probability * spikes.whole_account)
        out.append(f)
    return out
