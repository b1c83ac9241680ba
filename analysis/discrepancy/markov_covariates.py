"""Whether the slow state a Markov bias would name is tied to what the rig logged.

A Gauss–Markov bias is a stationary random process: it follows no input of the
procedure except by chance. Slow structure that is not one can still fit its
spectrum, and on a short record, where τ is comparable to the record, it
imitates any slow curve: on issue 29's fourth held-out set the 12-minute, 500 Hz
thermal shock named markov_bias at ≥ 0.8 for seven kinds of deterministic or
input-driven structure (a bias ∝ d²T/dt², an offset while the table turns, a
random walk advancing only while it turns, a Markov σ growing with temperature,
a bias in one 15° sector of the table angle, an unlogged second axis indexed
five times, vibration rectified in |ω|), past the stationarity test, the probes
and the level and flicker tests (process_shape.py).

So before a Markov bias is named, its reading is held against a small library of
what the log carries, on window means of the one-second residual (at most
``MAX_WINDOWS`` windows):

* in the mean: d²T/dt² and dT/dt of the chamber, the table turning, the time it
  has spent turning, bands of |ω|, 15° sectors of the table angle, each a
  profile likelihood ratio against the Markov reading alone (the process's
  variance and τ, and the common scale, profiled on a grid about the fit; the
  base's columns, bias, time, T, ω and ω·ΔT, fitted in both);
* in the increments: the innovations of the Markov reading (Cholesky of its
  window-mean covariance) whose variance follows chamber T, the turning or
  |ω| (Koenker's score test), or whose largest one is a jump (a step or a pulse).

Each statistic is turned into a p-value in a finite-sample form (``_p_values``)
and the smallest of them is the test statistic; its limit is the
``COVARIATE_ALPHA`` point of the same smallest p-value on a parametric bootstrap
of the fitted Markov reading (``COVARIATE_DRAWS`` draws of its window means,
from their own generator), so the library's size costs no
level. The nominal level is half the 0.5 % budget: the first form (χ² for the
mean families, kurtosis for jumps) refused 9 of 400 true 10σ Markov records on
the own thermal shock at a nominal 0.5 %, the finite-sample forms 5 of 400 (the
fitted reading is an estimate; its draws are exact); measured figures at the
level used are in docs/discrepancy-validation.md and
``benchmarks/markov_covariates_calibration.py``. The test runs only when a Markov
bias is about to be named (about 0.07 s on a 15-minute record, 0.23 s on a
2.6-hour 100 Hz one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg, signal, stats

from gyrocal.analysis.discrepancy.arbitration import next_best_or_none
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import EffectScores, Fit, order_statistic_quantile
from gyrocal.analysis.discrepancy.segments import Bins
from gyrocal.analysis.discrepancy.stochastic import (
    MARKOV,
    StochasticCandidate,
    fine_bins,
    gm_bin_spectrum,
    noise_bin_spectra,
)

#: Level of the test: a true Markov bias is refused in about this fraction of records.
COVARIATE_ALPHA = 0.0015
#: Parametric-bootstrap draws of the fitted Markov reading, and their generator's seed.
COVARIATE_DRAWS = 600
COVARIATE_SEED = 2931
#: At most this many windows of the one-second residual (the covariance is dense).
MAX_WINDOWS = 120
#: The profile grid: τ about the fitted one; the process's variance relative to the fitted one.
TAU_FACTORS = tuple(np.geomspace(0.25, 4.0, 9))
VARIANCE_RATIOS = tuple(np.geomspace(0.01, 4.0, 10))
#: Savitzky–Golay window (s) of the chamber temperature's derivatives, and |ω| still below (deg/s).
SMOOTH_S = 61
STILL_DPS = 0.05
#: Edges (deg/s) of the |ω| bands, and the width (deg) of the table-angle sectors.
RATE_EDGES_DPS = (STILL_DPS, 0.5, 2.0, 8.0, 30.0, 120.0, math.inf)
SECTOR_DEG = 15.0


@dataclass(frozen=True)
class Family:
    """One covariate of the library: what it is in words, and its columns (mean) or its z (variance)."""

    key: str
    words: str
    columns: np.ndarray
    #: "mean": columns in the mean; "variance": the z the innovations' variance is tested against
    kind: str = "mean"


@dataclass(frozen=True)
class CovariateVerdict:
    """The smallest p-value over the library, its limit, the family behind it; ``why`` when it fires."""

    min_p: float
    limit: float
    family: str
    why: str | None


def _sectors(angle_deg: np.ndarray, index: np.ndarray, n_bins: int) -> np.ndarray:
    """Fraction of each bin spent in each table-angle sector (bins × sectors)."""
    count = int(round(360.0 / SECTOR_DEG))
    sector = np.floor(np.mod(angle_deg, 360.0) / SECTOR_DEG).astype(np.int64) % count
    return _fractions(sector, count, index, n_bins)


def _fractions(code: np.ndarray, count: int, index: np.ndarray, n_bins: int) -> np.ndarray:
    table = np.bincount(index * count + code[: index.size], minlength=n_bins * count)
    table = table.reshape(n_bins, count).astype(float)
    return table / np.maximum(table.sum(axis=1, keepdims=True), 1.0)


def _derivatives(temp_bins: np.ndarray, width_s: float) -> tuple[np.ndarray, np.ndarray]:
    """dT/dt (°C/min) and d²T/dt² (°C/min²) of the binned chamber temperature, smoothed."""
    n = temp_bins.size
    window = min(max(int(SMOOTH_S / width_s), 5), n)
    window -= 1 - window % 2            # odd
    if window < 5:
        return np.zeros(n), np.zeros(n)
    step_min = width_s / 60.0
    first = signal.savgol_filter(temp_bins, window, 3, deriv=1, delta=step_min)
    second = signal.savgol_filter(temp_bins, window, 3, deriv=2, delta=step_min)
    return first, second


def library(ctx: Context, bins: Bins) -> tuple[np.ndarray, list[Family]]:
    """The base's nuisance columns and the covariate families, on the one-second bins."""
    log = ctx.log
    index = np.arange(bins.n_samples) // bins.samples_per_bin
    rate = bins.mean(log.table_rate_dps)
    temp = bins.mean(log.chamber_temp_c)
    abs_rate = np.abs(log.table_rate_dps)
    turning = bins.mean((abs_rate > STILL_DPS).astype(float))
    bands = _fractions(np.searchsorted(RATE_EDGES_DPS, abs_rate, side="right"), len(RATE_EDGES_DPS) + 1,
                       index, bins.n_bins)[:, 1:]
    sectors = _sectors(ctx.builder.history.angle_deg, index, bins.n_bins)
    first, second = _derivatives(temp, bins.width_s)
    t = bins.centre_s - bins.centre_s.mean()
    nuisance = np.column_stack([np.ones(bins.n_bins), t, temp, rate, rate * (temp - temp.mean())])
    # seconds the table has turned so far: a bias that grows with wear or heating of the turning
    turned = np.cumsum(turning) * bins.width_s
    families = [
        Family("d2T", "slow structure following d²T/dt² of the chamber temperature", second[:, None]),
        Family("dT", "slow structure following dT/dt of the chamber temperature", first[:, None]),
        Family("turning", "a bias while the table turns", turning[:, None]),
        Family("turned", "a bias growing with the time the table has spent turning", turned[:, None]),
        Family("bands", "a bias that depends on |table rate| by band", bands),
        Family("sectors", "a bias that depends on the table angle by 15° sector", sectors),
        Family("var_T", "a random process whose size changes with chamber temperature", temp, "variance"),
        Family("var_turning", "a random process that moves at another pace while the table turns",
               turning, "variance"),
        Family("var_rate", "a random process whose size changes with |table rate|",
               np.log1p(bins.mean(abs_rate)), "variance"),
    ]
    return nuisance, families


def windows(x: np.ndarray, width: int) -> np.ndarray:
    m = x.shape[0] // width
    return x[: m * width].reshape(m, width, *x.shape[1:]).mean(axis=1)


def window_covariance(spectrum: np.ndarray, n: int, width: int, m: int) -> np.ndarray:
    """Toeplitz covariance of ``m`` window means (``width`` bins each) of the circulant process."""
    acov = np.fft.irfft(np.where(np.arange(spectrum.size) == 0, 0.0, spectrum), 2 * n)[:n]
    d = np.arange(-(width - 1), width)
    weights = (width - np.abs(d)) / float(width * width)
    lags = np.abs(np.arange(m)[:, None] * width + d[None, :])
    return linalg.toeplitz(acov[np.minimum(lags, n - 1)] @ weights)


@dataclass(frozen=True)
class Grid:
    """The Markov reading's spectra over the profile grid, at the 2n-circulant's frequencies."""

    fitted: np.ndarray
    spectra: list[np.ndarray]


def profile_grid(noise: NoiseModel, bins: Bins, fs_hz: float, markov: StochasticCandidate) -> Grid:
    n = bins.n_bins
    omega = np.pi * np.arange(n + 1) / n
    white_var, flicker, rest = noise_bin_spectra(noise, bins, fs_hz, omega)
    base = markov.white_scale * white_var + markov.flicker_scale * flicker + rest
    sigma, tau = markov.params["sigma_dph"], markov.params["tau_s"]
    spectra = [base]
    for factor in TAU_FACTORS:
        unit = gm_bin_spectrum(sigma, tau * factor, bins.width_s, omega)
        spectra += [base + ratio * unit for ratio in VARIANCE_RATIOS]
    fitted = base + gm_bin_spectrum(sigma, tau, bins.width_s, omega)
    clean = [np.where(np.isfinite(s), s, 0.0) for s in spectra]
    return Grid(np.where(np.isfinite(fitted), fitted, 0.0), clean)


def _orthonormal(columns: np.ndarray) -> np.ndarray:
    q, r = np.linalg.qr(columns)
    diag = np.abs(np.diag(r))
    return q[:, diag > 1e-8 * max(float(diag.max(initial=0.0)), 1e-300)]


@dataclass(frozen=True)
class Profiled:
    """Per family: the profile log-likelihood over the grid (columns: data, draws); H0's innovations."""

    loglik: dict[str, np.ndarray]
    dof: dict[str, int]
    innovations: np.ndarray


@dataclass(frozen=True)
class Whitened:
    """One grid point's whitening: ½ log det, the whitened data, the whitened base's basis, the
    residual sum of squares beside the base and the sum of squares the base explains, and the
    whitened extra columns (solved in the same triangular solve as the data)."""

    half_logdet: float
    white: np.ndarray
    base: np.ndarray
    rss0: np.ndarray
    explained0: np.ndarray
    extra: np.ndarray


def stack(y: np.ndarray, nuisance: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
    """The right-hand sides of ``whiten``: data, base and extra columns side by side, built once."""
    return np.hstack([y, nuisance] if extra is None else [y, nuisance, extra])


def whiten(cov: np.ndarray, rhs: np.ndarray, n_data: int, n_nuisance: int) -> Whitened:
    """Cholesky of one grid point's covariance and ONE triangular solve of all of ``rhs`` (``stack``).

    The grid has 91 points and the data hundreds of draws: one solve of the stacked columns
    a point, not one per family, is what keeps the test cheap (each column is solved alone,
    so the figures are those of separate solves).
    """
    chol = np.linalg.cholesky(cov)
    solved = linalg.solve_triangular(chol, rhs, lower=True)
    white = solved[:, :n_data]
    base = _orthonormal(solved[:, n_data:n_data + n_nuisance])
    explained0 = np.sum((base.T @ white) ** 2, axis=0)
    rss0 = np.sum(white * white, axis=0) - explained0
    return Whitened(float(np.sum(np.log(np.diag(chol)))), white, base, rss0, explained0,
                    solved[:, n_data + n_nuisance:])


def _profile(y: np.ndarray, nuisance: np.ndarray, families: list[Family], grid: Grid, n: int,
             width: int) -> Profiled:
    """Each mean family's and H0's concentrated log-likelihood, maximised over the grid."""
    m = y.shape[0]
    means = [f for f in families if f.kind == "mean"]
    edges = np.cumsum([0] + [f.columns.shape[1] for f in means])
    rhs = stack(y, nuisance, np.hstack([f.columns for f in means]))
    best: dict[str, np.ndarray] = {"": np.full(y.shape[1], -np.inf)}
    dof: dict[str, int] = {}
    innovations = np.zeros_like(y)
    for spectrum in grid.spectra:
        w = whiten(window_covariance(spectrum, n, width, m), rhs, y.shape[1], nuisance.shape[1])
        ll0 = -0.5 * m * np.log(w.rss0 / m) - w.half_logdet
        better = ll0 > best[""]
        if better.any():
            rest = w.white - w.base @ (w.base.T @ w.white)
            innovations[:, better] = rest[:, better] / np.sqrt(w.rss0[better] / m)
        best[""] = np.maximum(best[""], ll0)
        bases = [_orthonormal(np.hstack([w.base, w.extra[:, a:b]])) for a, b in zip(edges[:-1], edges[1:], strict=True)]
        # every family's basis against the data in one product; the row sums below are per family
        squares = (np.hstack(bases).T @ w.white) ** 2
        total = w.rss0 + w.explained0
        row = 0
        for f, q in zip(means, bases, strict=True):
            dof[f.key] = q.shape[1] - w.base.shape[1]
            row += q.shape[1]
            if dof[f.key] == 0:
                continue
            rss = total - np.sum(squares[row - q.shape[1]:row], axis=0)
            ll = -0.5 * m * np.log(rss / m) - w.half_logdet
            best[f.key] = np.maximum(best.get(f.key, ll), ll)
    return Profiled(best, dof, innovations)


def _p_values(profiled: Profiled, families: list[Family], z_windows: dict[str, np.ndarray], n_nuisance: int
              ) -> dict[str, np.ndarray]:
    """Each family's p-value (and that of jumps) for the data and each draw, in finite-sample forms.

    The smallest over the library is calibrated on the draws anyway, but the closer each
    p-value is to uniform, the less one family's tail sets the limit for all: a mean
    family's likelihood ratio is read as the F statistic it equals at a common grid point
    (the χ² form of 23 sector columns on 150 windows is anti-conservative), jumps as the
    largest innovation against m Gaussian ones (Šidák), not as a kurtosis.
    """
    out: dict[str, np.ndarray] = {}
    e = profiled.innovations
    m = e.shape[0]
    for f in families:
        if f.kind == "variance":
            z = z_windows[f.key]
            z = z - z.mean()
            if not float(z @ z) > 0:
                continue
            u = e * e
            u = u - u.mean(axis=0)
            r2 = (z @ u) ** 2 / (float(z @ z) * np.maximum(np.sum(u * u, axis=0), 1e-300))
            out[f.key] = stats.chi2.sf(m * r2, 1)
        elif profiled.dof.get(f.key, 0) > 0 and f.key in profiled.loglik:
            k = profiled.dof[f.key]
            rest = max(m - n_nuisance - k, 1)
            lr = np.maximum(2.0 * (profiled.loglik[f.key] - profiled.loglik[""]), 0.0)
            out[f.key] = stats.f.sf(np.expm1(lr / m) * rest / k, k, rest)
    biggest = np.abs(e).max(axis=0)
    out["jumps"] = -np.expm1(m * np.log1p(-2.0 * stats.norm.sf(biggest)))
    return out


JUMPS = "slow structure that moves in jumps (steps or pulses), not a Gaussian wander"


def _largest(family: Family, y0: np.ndarray, nuisance: np.ndarray, cov: np.ndarray) -> str:
    """Which band or sector carries the largest bias (GLS beside the base under the Markov reading)."""
    chol = np.linalg.cholesky(cov)
    x = linalg.solve_triangular(chol, np.hstack([nuisance, family.columns]), lower=True)
    coef = np.linalg.lstsq(x, linalg.solve_triangular(chol, y0, lower=True), rcond=None)[0]
    part = coef[nuisance.shape[1]:]
    k = int(np.argmax(np.abs(part - np.median(part))))
    if family.key == "sectors":
        return f" (largest in {k * SECTOR_DEG:.0f}–{(k + 1) * SECTOR_DEG:.0f}°)"
    low, high = RATE_EDGES_DPS[k], RATE_EDGES_DPS[k + 1]
    return f" (largest at {low:g}–{high:g} deg/s)" if math.isfinite(high) else f" (largest above {low:g} deg/s)"


def covariate_test(ctx: Context, fit: Fit, markov: StochasticCandidate) -> CovariateVerdict:
    """The library against the Markov reading on the one-second residual; ``why`` says what it follows."""
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    n = bins.n_bins
    width = max(1, -(-n // MAX_WINDOWS))
    if n // width < 24:
        return CovariateVerdict(1.0, 0.0, "", None)
    nuisance, families = library(ctx, bins)
    grid = profile_grid(ctx.noise, bins, ctx.fs_hz, markov)
    # the draws are the fitted reading's window means, drawn from their covariance directly (the
    # same Gaussian law as window means of a simulated one-second series, a tenth of the cost)
    m = n // width
    fitted = np.linalg.cholesky(window_covariance(grid.fitted, n, width, m))
    draws = fitted @ np.random.default_rng(COVARIATE_SEED).standard_normal((m, COVARIATE_DRAWS))
    y = np.column_stack([windows(bins.mean(ctx.resid_full(fit)), width), draws])
    by_key = {f.key: windows(f.columns, width) for f in families}
    windowed = [Family(f.key, f.words, by_key[f.key], f.kind) for f in families]
    profiled = _profile(y, windows(nuisance, width), windowed, grid, n, width)
    p = _p_values(profiled, windowed, by_key, nuisance.shape[1])
    keys = list(p)
    matrix = np.vstack([p[k] for k in keys])
    min_p = matrix.min(axis=0)
    limit = -order_statistic_quantile(-min_p[1:], 1.0 - COVARIATE_ALPHA)
    key = keys[int(np.argmin(matrix[:, 0]))]
    words = JUMPS if key == "jumps" else next(f.words for f in families if f.key == key)
    why = None
    if min_p[0] < limit:
        if key in ("sectors", "bands"):
            family = next(f for f in windowed if f.key == key)
            words += _largest(family, y[:, 0], windows(nuisance, width), fitted @ fitted.T)
        why = (f"{words}, which a Markov bias (σ {markov.params['sigma_dph']:.3g} deg/h, τ "
               f"{markov.params['tau_s']:.0f} s) would absorb: tied to what the rig logged (p "
               f"{min_p[0]:.2g}, limit {limit:.2g} at α = {COVARIATE_ALPHA:g} on {COVARIATE_DRAWS} draws "
               "of the Markov fit)")
    return CovariateVerdict(float(min_p[0]), float(limit), key, why)


def unless_tied_to_covariates(ctx: Context, fit: Fit, markov: StochasticCandidate, ranked: dict[str, float],
                              scores: dict[str, EffectScores]) -> tuple[str | None, str | None]:
    """(MARKOV, None) if the Markov reading follows nothing the rig logged; else (the next best or None, why)."""
    verdict = covariate_test(ctx, fit, markov)
    if verdict.why is None:
        return MARKOV, None
    return next_best_or_none(ctx, fit, ranked, scores), verdict.why
