"""Whether the white-noise level itself changes with |rate|, temperature or time (issue 29).

Every other test of the workflow looks at bin means: a catalogue effect, a
probe, the adequacy test all ask whether the *mean* of the residual has a
shape. A gyro whose white noise grows with |ω| (or with temperature, or drifts
over the night) leaves the bin means flat and only their scatter changes, so
on the held-out set such a record was called unexplained in 0 of 9 runs and
nothing at all was said about it.

The test reads the scatter at the sample level. The refitted model's
full-rate residual is cut into short windows (at least ``MIN_WINDOW_SAMPLES``
samples, at most ``MAX_WINDOWS`` of them); in each window a mean
and a slope are removed, so anything slow (a missing catalogue effect, the
Markov bias, flicker, a thermal drift) leaves the within-window scatter
alone, and samples beyond ``CLIP_SIGMA`` robust standard deviations of their
window are clipped (about the window's line, refitted after each clip) so a
single spike cannot pose as a noise level. Windows
where the table rate is not constant are left out (a slew puts the
rate-dependent terms' curvature into the scatter); their neighbours are kept
(leaving them out too lost most of the top-rate dwells: on Q2 the expected
t² of a 10σ change fell from 31 to 3.5). The log
of each window variance is then regressed, weighted by its sampling variance
ψ'(ν/2), on one covariate at a time — |rate|, ln(1 + |rate|/1 deg/s), chamber
temperature, time — a Bartlett-type test of a log-linear variance law. Each
slope's t² uses the dispersion estimated from the data, so colored or
non-Gaussian noise that is the same everywhere does not inflate it.

The statistic is the largest t² over the covariates; its threshold is the
(1 − ``ALPHA_NOISE_LEVEL``) point of the same maximum on simulated
effect-free draws (``_family_threshold``: the draws share the covariates, so
their correlation is accounted for). ``ALPHA_NOISE_LEVEL`` = 0.5 %: this test may
add no more than that to the family-wise false alarms.

Measured (``benchmarks/validate_noise_level.py``, the test on the refitted
base of simulated logs, 100 draws per row): effect-free controls fired 0 of
600 on P1, Q1–Q3 and the benchmark's 1–2 Hz profiles L1, L2, and 0 of 30 on
the static P3 (Wilson 95 % upper bound 0.6 %; an earlier run of the same
design with two medians per window, 1 of 600 and 1 of 20 Q2 seeds);
σ0·(1 + k|ω|) at expected likelihood ratio 10² was found in 100 of 100 on
Q1, Q2, Q3, L1 and L2, and 22 of 100 on P1 — P1's two top rates are never
held steady at 10 deg/s² (their dwells are all slew), so only 11 of the 100
expected LR lie in steady windows. 10σ dead_zone, markov_bias (τ 30 s,
300 s), sf_nonlinearity_quadratic/cubic, periodic_interference,
table_angle_harmonic, temp_rate_bias, thermal_lag left *unmodelled* leave
the statistic exactly as the noise draw gives it (Q2, P1, 20 seeds each: the
one firing seed fired for all of them alike). CPU: 0.01 s on P1, 0.015 s on
Q2, 0.06 s on P2 (930 000 samples), 0.6–0.8 s on 10 M samples at 250 Hz (the
overnight folder's size).

On a long, low-rate record of our own (``tests/support/discrepancy_long_record.py``: 20 h at
2.5 Hz, a plateau temperature cycle) the test fired on 2 of 200 effect-free controls (one
"grows with chamber temperature", one "falls with |rate| ×0.94"), though the simulated noise
there does not depend on |rate|. The second held-out set's first run saw it fire on 2 of 40 such
controls with "falls with |rate| ×0.971"; that text by itself says little (on our profile pure
white noise gives it at t² 1.2), and no mechanism tried here made it significant: an output LSB of 0.22 or
1 deg/h, 6 % more variance in temperature ramps, a 0.5″ or 2″ pulse counter all left t² ≤ 2.5
(docs/discrepancy-validation.md, "Long low-rate records").

Not judged when the model counts pulses (``quantization``) whose rate noise is
not small beside the white noise (over 1 % of its variance): a pulse
counter's error depends on how far the angle moves per sample, so its scatter
changes with |rate| by itself (on Q2, a pulse whose counting noise is 50 % of
the white variance fired 3 of 6, 10 % none of 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.special import polygamma

from gyrocal.analysis.discrepancy.adequacy import NOT_JUDGED
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import (
    Fit,
    Whitener,
    gls_fit,
    order_statistic_quantile,
    score_from_delta,
)
from gyrocal.analysis.discrepancy.segments import RATE_CHANGE_DPS
from gyrocal.analysis.discrepancy.signatures import effect_columns

#: Family-wise false-alarm rate this test may add.
ALPHA_NOISE_LEVEL = 0.005
#: Effect-free draws of the covariates' slopes for the threshold (cheap: one normal vector each).
N_NULL_DRAWS = 100000
#: A window has at least this many samples (ν = m − 2 after its mean and slope) ...
MIN_WINDOW_SAMPLES = 10
#: ... and a record has at most this many windows. Short windows keep more of each short dwell
#: between slews and leave anything slower than a fraction of a second out of the scatter.
MAX_WINDOWS = 20000
#: Samples beyond this many robust standard deviations of their window are clipped.
CLIP_SIGMA = 5.0
#: Pulse-counter rate-noise variance, as a fraction of the white noise's, above which the test
#: is not judged (its own scatter changes with the angle moved per sample).
QUANTIZATION_SHARE_MAX = 0.01
#: |rate| scale of the logarithmic rate covariate, deg/s.
RATE_SCALE_DPS = 1.0


@dataclass(frozen=True)
class Covariate:
    """One variable the noise level may follow: its per-window values and how to speak of it."""

    key: str
    values: np.ndarray
    #: the variable's own values per window (deg/s, °C, h) for the description
    shown: np.ndarray
    phrase: str
    unit: str


@dataclass(frozen=True)
class NoiseLevel:
    """The variance-heterogeneity test's outcome."""

    statistic: float            # largest t² of a log-variance slope
    threshold: float            # (1 − α) point of that maximum on effect-free draws
    covariate: str              # key of the covariate with the largest t² ("" if none)
    ratio: float                # σ at the covariate's high end over σ at its low end (fitted law)
    description: str
    windows: int
    not_judged: str = ""        # why the test was not run, if it was not
    slope: float = 0.0          # d ln σ² / d covariate of the fitted law

    @property
    def fires(self) -> bool:
        return not self.not_judged and self.statistic > self.threshold

    @property
    def note(self) -> str:
        """What the test found, for the result's notes."""
        if self.not_judged:
            return f"noise level against |rate|, temperature and time not judged: {self.not_judged}"
        verdict = self.description if self.fires else "the white-noise level is steady"
        return (f"{verdict}: largest log-variance slope t² {self.statistic:.1f} ({self.covariate}) over "
                f"{self.windows} steady windows, threshold {self.threshold:.1f} (noise_level.py)")

    @property
    def whole_account(self) -> float:
        """Probability that the noise level is constant: the claim odds rule on −log10 p scores."""
        if not self.fires:
            return 1.0
        return 1.0 - real_probability(score_from_delta(self.statistic, 1), score_from_delta(self.threshold, 1))


def noise_level_test(ctx: Context, after: Fit) -> NoiseLevel:
    """The test on the refitted model's full-rate residual (see the module docstring)."""
    why = _not_judged(ctx, after)
    if why:
        return NoiseLevel(0.0, math.inf, "", 1.0, "", 0, why)
    windows = _windows(ctx)
    log_var, nu, used = _window_log_variances(ctx.resid_full(after), windows, ctx.log.table_rate_dps)
    covariates = _covariates(ctx, windows, used)
    if len(log_var) < 20 or not covariates:
        return NoiseLevel(0.0, math.inf, "", 1.0, "", len(log_var), "too few steady windows")
    weight = 1.0 / polygamma(1, nu / 2.0)
    x = np.column_stack([c.values for c in covariates])
    t2, slopes = _slope_t2(x, log_var[:, None], weight)
    best = int(np.argmax(t2[:, 0]))
    threshold = _family_threshold(x, weight, ctx.rng)
    cov = covariates[best]
    ratio, description = _describe(cov, float(slopes[best, 0]))
    return NoiseLevel(float(t2[best, 0]), threshold, cov.key, ratio, description, len(log_var),
                      slope=float(slopes[best, 0]))


def judged_by_level(ctx: Context, after: Fit, found: list[FoundEffect], level: NoiseLevel) -> list[FoundEffect]:
    """The named effects with the probabilities a changing noise level leaves them.

    Bins where the noise is larger weigh too much in a likelihood that assumes it
    constant, so a named effect may be that weight and nothing more. Each named
    deterministic effect is refitted with the bin covariance scaled by the fitted
    variance law; one that no longer adds significantly (its own threshold) has its
    probability multiplied by ``level.whole_account``, as adequacy.py does for a probe.
    """
    if not level.fires or all(f.name in NOT_JUDGED for f in found):
        return found
    factor = np.exp(level.slope * _bin_covariate(ctx, level.covariate))
    scale = np.sqrt(factor / factor.mean())
    whitener = Whitener(ctx.whitener.covariance * np.outer(scale, scale))
    with_all = gls_fit(ctx.builder, whitener, ctx.y_bins, after.model).chi2
    out = []
    for f in found:
        if f.name not in NOT_JUDGED:
            without = gls_fit(ctx.builder, whitener, ctx.y_bins, after.model.without_effect(f.name)).chi2
            dof = max(len(effect_columns(f.name)), 1)
            if score_from_delta(without - with_all, dof) <= f.threshold:
                f = replace(f, probability=f.probability * level.whole_account)
        out.append(f)
    return out


def _bin_covariate(ctx: Context, key: str) -> np.ndarray:
    """The covariate of the fitted law on the workflow's bins."""
    log, bins = ctx.log, ctx.bins
    if key == "abs_rate":
        return np.abs(bins.mean(log.table_rate_dps))
    if key == "log_abs_rate":
        return np.log1p(np.abs(bins.mean(log.table_rate_dps)) / RATE_SCALE_DPS)
    if key == "temperature":
        return bins.mean(log.chamber_temp_c)
    return bins.centre_s / 3600.0


def _family_threshold(x: np.ndarray, weight: np.ndarray, rng: np.random.Generator) -> float:
    """(1 − α) point of the largest t² over the covariates on effect-free draws.

    On effect-free data the covariates' slopes are jointly normal with the
    correlation of the weighted, centred covariates (each t² is F(1, n − 2),
    n in the thousands), so a draw of the family is a draw of that normal
    vector: as exact as drawing every window's log-variance and refitting, and
    its cost does not grow with the record.
    """
    xc = x - (weight @ x) / weight.sum()
    gram = (xc * weight[:, None]).T @ xc
    d = np.sqrt(np.diag(gram))
    corr = gram / np.outer(d, d)
    z = rng.multivariate_normal(np.zeros(len(d)), corr, size=N_NULL_DRAWS, method="eigh")
    return order_statistic_quantile(np.max(z * z, axis=1), 1.0 - ALPHA_NOISE_LEVEL)


def _not_judged(ctx: Context, after: Fit) -> str:
    spec = after.model.effect("quantization")
    if spec is None or ctx.noise is None:
        return ""
    white = ctx.noise.white_sigma_dph(ctx.fs_hz) ** 2
    # a pulse q counted per sample: rate error (e_k − e_(k−1))/Δt with e uniform on [0, q), in deg/h
    pulse = (spec["pulse_arcsec"] / 3600.0 * ctx.fs_hz * 3600.0) ** 2 / 6.0
    if white > 0 and pulse <= QUANTIZATION_SHARE_MAX * white:
        return ""
    return (f"the pulse counter's rate noise ({math.sqrt(pulse):.3g} deg/h per sample) is not small beside "
            "the white noise, and its scatter changes with the angle moved per sample by itself")


@dataclass(frozen=True)
class Windows:
    per_window: int
    count: int

    def shape(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x[: self.per_window * self.count], dtype=float).reshape(self.count, self.per_window)


def _windows(ctx: Context) -> Windows:
    n = len(ctx.log.t_s)
    per = max(MIN_WINDOW_SAMPLES, math.ceil(n / MAX_WINDOWS))
    return Windows(per, n // per)


def _window_log_variances(resid_dph: np.ndarray, windows: Windows, rate_dps: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ln of each steady window's variance about its own line, its ν, and which windows were used."""
    r = windows.shape(resid_dph)
    rate = windows.shape(rate_dps)
    moving = np.ptp(rate, axis=1) > RATE_CHANGE_DPS + 1e-6 * np.max(np.abs(rate), axis=1)
    steady = ~moving
    m = windows.per_window
    r = _detrended(r[steady])
    # the window's robust σ: its median absolute residual (one partition; the median proper
    # averages two middle values, a second partition on 10 M samples for nothing)
    scale = 1.4826 * np.partition(np.abs(r), m // 2, axis=1)[:, m // 2: m // 2 + 1]
    # a spike pulls its window's line too, so clip about the line and fit it again, twice
    for _ in range(2):
        r = _detrended(np.clip(r, -CLIP_SIGMA * scale, CLIP_SIGMA * scale))
    nu = np.full(r.shape[0], float(m - 2))
    ss = np.einsum("ij,ij->i", r, r)
    good = ss > 0
    used = np.flatnonzero(steady)[good]
    # ln(s²) has mean ln σ² + ψ(ν/2) − ln(ν/2): a constant when ν is, so the slopes need no correction
    return np.log(ss[good] / nu[good]), nu[good], used


def _detrended(r: np.ndarray) -> np.ndarray:
    """Each row less its own least-squares line."""
    k = np.arange(r.shape[1]) - 0.5 * (r.shape[1] - 1)
    r = r - r.mean(axis=1, keepdims=True)
    return r - np.outer(r @ k / (k @ k), k)


def _covariates(ctx: Context, windows: Windows, used: np.ndarray) -> list[Covariate]:
    log = ctx.log
    abs_rate = np.abs(windows.shape(log.table_rate_dps).mean(axis=1))[used]
    temp = windows.shape(log.chamber_temp_c).mean(axis=1)[used]
    hours = (windows.shape(log.t_s).mean(axis=1)[used] - float(log.t_s[0])) / 3600.0
    out: list[Covariate] = []
    if np.ptp(abs_rate) > 1e-3:
        out.append(Covariate("abs_rate", abs_rate, abs_rate, "|rate|", "deg/s"))
        out.append(Covariate("log_abs_rate", np.log1p(abs_rate / RATE_SCALE_DPS), abs_rate, "|rate|", "deg/s"))
    if np.ptp(temp) > 1.0:
        out.append(Covariate("temperature", temp, temp, "chamber temperature", "°C"))
    if hours.size:
        out.append(Covariate("time", hours, hours, "time in the record", "h"))
    return out


def _slope_t2(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t² and slope of the weighted regression of each column of ``y`` on each column of ``x``.

    Shapes: x (n, c), y (n, d) → (c, d). The dispersion is estimated from the data (n − 2 dof).
    """
    sw = w.sum()
    xc = x - (w @ x) / sw
    yc = y - (w @ y) / sw
    sxx = w @ (xc * xc)                               # (c,)
    sxy = (xc * w[:, None]).T @ yc                    # (c, d)
    syy = w @ (yc * yc)                               # (d,)
    slope = sxy / sxx[:, None]
    explained = slope * sxy
    rss = np.maximum(syy[None, :] - explained, 1e-300)
    t2 = explained / (rss / (len(w) - 2))
    return t2, slope


def _describe(cov: Covariate, slope: float) -> tuple[float, str]:
    """σ's change over the covariate's range under the fitted law, in words."""
    lo, hi = int(np.argmin(cov.shown)), int(np.argmax(cov.shown))
    ratio = math.exp(0.5 * slope * (cov.values[hi] - cov.values[lo]))
    verb = "grows" if ratio >= 1.0 else "falls"
    if cov.key == "time":
        text = (f"white-noise level drifts over the record (×{ratio:.3g} from the start to "
                f"{cov.shown[hi]:.2g} h)")
    else:
        text = (f"white-noise level {verb} with {cov.phrase} (×{ratio:.3g} from {cov.shown[lo]:.3g} to "
                f"{cov.shown[hi]:.3g} {cov.unit})")
    return ratio, text
