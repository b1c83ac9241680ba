"""A Gauss–Markov bias (and its slow limit, a rate random walk) judged over the whole record.

The quiet-segment Allan curve (``noise_model.estimate_noise``) sees only what
fits inside the quiet segments: a Markov bias with a correlation time of a few
hundred seconds is invisible when those segments last ten minutes, and a
random walk is never observable there. Both leave their mark on the *whole*
residual of the deterministic fit, at frequencies below a segment's length,
so they are judged on it, as alternatives to the noise model:

* H0: the noise model's spectrum of bin means with its white level and its
  flicker level scaled by free factors a and b (the quiet-segment N is an
  estimate; the model file's B cannot be checked in minutes of quiet data);
* H_markov: H0 + a first-order Gauss–Markov process (σ, τ), τ from half a bin
  to twice the record.

A rate random walk is the τ → ∞ limit of the same family (σ²/τ fixed): a
Markov process much slower than the record cannot be told from one, so it is
not a rival hypothesis but a reading of the fit (``at_rrw_limit``). Scored as
separate alternatives, the two split the evidence for a slow Markov process
between them (on a 1-hour record, τ = 300 s gave likelihood ratios 198 and
197), and the random walk's one parameter fewer won.

The likelihood is Whittle's (the periodogram of the bin means against each
model's spectrum), which is what makes this affordable: every candidate
spectrum is evaluated on the real residual *and* on several hundred
simulated effect-free residuals with one matrix product, so the threshold is
calibrated by simulation like the deterministic library's and the
statistic is the same on both (the nulls are drawn in the periodogram's own
distribution, see ``WhittleTest``, and each draw's likelihoods are refined
off the grid as the data's are: whittle_null.py). Whittle's likelihood is the exact one's
large-sample form; ``tests/reports/discrepancy/test_stochastic.py`` checks
that its likelihood ratio agrees with the exact Gaussian likelihood ratio of
the time-domain bin covariance (``NoiseModel.bin_covariance``, scipy's dense
multivariate normal) on a simulated Markov record.

Spectra of bin means (width D): white rate noise → its bin variance, flat;
a Gauss–Markov process → AR(1) with φ = e^(−D/τ) plus a white part (the
averaging inside a bin; the same closed form as ``bin_covariance``); a random
walk of rate (q = (K/60)² (deg/h)²/s) → a discrete walk of step variance q·D,
qD / (4 sin²(ω/2)). Gaps in a run folder's time axis are ignored here (the
bins are taken as consecutive), which only blurs the lowest frequencies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import order_statistic_quantile, score_from_delta
from gyrocal.analysis.discrepancy.segments import Bins, make_bins
from gyrocal.analysis.discrepancy.whittle_null import Spectra, refined_logliks
from gyrocal.models.noise import flicker_bank

#: Width of the fine bins the test is run on (s), and at most this many of them.
FINE_BIN_S = 1.0
MAX_FINE_BINS = 1 << 18


def fine_bins(t_s: np.ndarray, fs_hz: float) -> Bins:
    """About one-second bins over the whole record (wider only past MAX_FINE_BINS of them)."""
    return make_bins(t_s, fs_hz, max_bins=MAX_FINE_BINS, min_width_s=FINE_BIN_S)


#: Free scale of the null's white level, and the grid it is profiled on.
WHITE_SCALES = np.geomspace(0.7, 1.4, 8)
#: Free scale of the model file's flicker (bias instability) term: B is not observable in
#: minutes of quiet data, and a Markov bias must not be called out merely because B is off.
FLICKER_SCALES = np.array([0.5, 0.7, 1.0, 1.4, 2.0, 3.0])
#: Grid of the added process's low-frequency power relative to the white level.
POWER_RATIOS = np.geomspace(0.03, 3.0e4, 15)
#: Number of correlation times tried, log-spaced from half a bin to RRW_LIMIT of the record.
TAU_POINTS = 14
#: A Markov process slower than this fraction of the record is, to the record, a rate random
#: walk (q = 2σ²/τ): the random walk is the τ → ∞ limit of the same family, not a rival.
RRW_LIMIT = 2.0

MARKOV = "markov_bias"


def gm_bin_spectrum(sigma_dph: float, tau_s: float, width_s: float, omega: np.ndarray) -> np.ndarray:
    """Spectrum (deg/h)² of the bin means of a Gauss–Markov process (exact: AR(1) + white)."""
    x = width_s / tau_s
    one_minus = -math.expm1(-x)
    var = 2.0 * sigma_dph**2 / x * (1.0 - one_minus / x)
    if x > 40.0:  # far faster than a bin: white at bin level
        return np.full(np.shape(omega), var)
    phi = math.exp(-x)
    ar_var = sigma_dph**2 * (one_minus / x) ** 2 * math.exp(x)
    ar = ar_var * (1.0 - phi * phi) / (1.0 - 2.0 * phi * np.cos(omega) + phi * phi)
    return (var - ar_var) + ar


def rrw_bin_spectrum(k_deg_per_h_rth: float, width_s: float, omega: np.ndarray) -> np.ndarray:
    """Pseudo-spectrum of the bin means of a rate random walk K (deg/h/√h)."""
    q = (k_deg_per_h_rth / 60.0) ** 2
    return q * width_s / (4.0 * np.sin(0.5 * omega) ** 2)


def periodogram(x: np.ndarray) -> np.ndarray:
    """|DFT|²/n at ω_k = 2πk/n, k = 1…⌊(n−1)/2⌋ (the mean and Nyquist left out); columns kept."""
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    k_max = (n - 1) // 2
    spectrum = np.fft.rfft(x, axis=0)[1: k_max + 1]
    return (spectrum.real**2 + spectrum.imag**2) / n


def noise_bin_spectra(noise: NoiseModel, bins: Bins, fs_hz: float, omega: np.ndarray
                      ) -> tuple[float, np.ndarray, np.ndarray]:
    """The noise model's spectrum of bin means at ``omega``: (white level, flicker part, the rest).

    Kept apart so that a test can evaluate the same spectrum at every ordinate of a
    record (process_shape.py simulates the fitted process from it), not only at the
    Whittle test's band means.
    """
    width_s = bins.width_s
    white_var = 3600.0 * noise.arw_deg_per_rth**2 * fs_hz / bins.samples_per_bin
    flicker = np.zeros_like(omega)
    if noise.bias_instability_dph > 0:
        taus, sigmas = flicker_bank(noise.bias_instability_dph)
        for sigma, tau in zip(sigmas.tolist(), taus.tolist(), strict=True):
            flicker = flicker + gm_bin_spectrum(sigma, tau, width_s, omega)
    rest = np.zeros_like(omega)
    if noise.has_markov:
        rest = rest + gm_bin_spectrum(noise.markov_sigma_dph, noise.markov_tau_s, width_s, omega)
    if noise.quantization_arcsec > 0:
        rest = rest + (noise.quantization_arcsec / width_s) ** 2 * (2.0 - 2.0 * np.cos(omega))
    if noise.rrw_deg_per_h_rth > 0:
        rest = rest + rrw_bin_spectrum(noise.rrw_deg_per_h_rth, width_s, omega)
    return white_var, flicker, rest


@dataclass(frozen=True)
class StochasticCandidate:
    """One stochastic alternative: its fitted parameters, LR on the data and on each null."""

    name: str
    params: dict[str, float]
    lr: float
    dof: int
    null_lr: np.ndarray
    white_scale: float
    #: τ at the top of the range: slower than the record can show, a rate random walk to the data
    at_rrw_limit: bool = False
    flicker_scale: float = 1.0
    #: each null draw's ratio taken at the grid, as before whittle_null.py: the catalogue's threshold
    #: still reads it (markov_threshold.py)
    grid_null_lr: np.ndarray | None = None

    @property
    def rrw_deg_per_h_rth(self) -> float:
        """The random walk a Markov process this slow looks like: q = 2σ²/τ, K = 60·√q."""
        return 60.0 * math.sqrt(2.0 * self.params["sigma_dph"] ** 2 / self.params["tau_s"])

    @property
    def score(self) -> float:
        return score_from_delta(self.lr, self.dof)

    def null_scores(self) -> np.ndarray:
        return np.array([score_from_delta(float(v), self.dof) for v in self.null_lr])

    def grid_null_scores(self) -> np.ndarray:
        """The null scores with each draw's ratio at the grid (``null_scores`` when there are none)."""
        if self.grid_null_lr is None:
            return self.null_scores()
        return np.array([score_from_delta(float(v), self.dof) for v in self.grid_null_lr])


def frequency_bands(k_max: int, single: int = 32, ratio: float = 1.05) -> np.ndarray:
    """Edges (ordinate indices 0…k_max) of bands: the first ``single`` ordinates alone, then
    bands growing by ``ratio``; a few hundred bands carry a record of any length."""
    edges = list(range(min(single, k_max) + 1))
    while edges[-1] < k_max:
        edges.append(min(k_max, max(edges[-1] + 1, int(round(edges[-1] * ratio)))))
    return np.array(edges)


class WhittleTest:
    """Whittle likelihoods of the residual's bin means under H0 and H_markov.

    The bins here are fine (about a second: ``fine_bins``), not the GLS bins,
    so correlation times of seconds are not averaged away; the periodogram is
    averaged over frequency bands (exact for the lowest ordinates, bands 5 %
    wide above), so the likelihood of a 20-hour record costs a few hundred
    terms. Under H0 each band mean is S·Gamma(m, 1)/m, so the effect-free
    nulls are drawn directly in that form.
    """

    def __init__(self, noise: NoiseModel, bins: Bins, fs_hz: float) -> None:
        n = bins.n_bins
        self.width_s = bins.width_s
        self.duration_s = n * bins.width_s
        self.edges = frequency_bands((n - 1) // 2)
        self.counts = np.diff(self.edges).astype(float)
        k = np.arange(1, (n - 1) // 2 + 1)
        omega_k = 2.0 * math.pi * k / n
        self.omega = np.add.reduceat(omega_k, self.edges[:-1]) / self.counts
        white_var, flicker, rest = noise_bin_spectra(noise, bins, fs_hz, self.omega)
        self.white_var, self.flicker, self.rest = white_var, flicker, rest
        self.flicker_scales = FLICKER_SCALES if noise.bias_instability_dph > 0 else np.ones(1)
        self.tau_bounds_s = (max(0.5 * self.width_s, 1.0), max(RRW_LIMIT * self.duration_s, 2.0 * self.width_s))
        self.taus_s = np.geomspace(*self.tau_bounds_s, TAU_POINTS)
        units = [gm_bin_spectrum(1.0, float(tau), self.width_s, self.omega) for tau in self.taus_s]
        # the power grid is relative to the null's own level (its median over the bands), not
        # to the white part alone, which is 0 for a pulse-counting gyro whose noise is all Q
        reference = float(np.median(white_var + flicker + rest))
        if not reference > 0:
            raise ValueError("the noise model has no power at all: nothing to test a Markov bias against")
        rows: list[np.ndarray] = []
        self.labels: list[tuple[bool, float, float, float, float]] = []   # alternative?, a, b, σ, τ
        for a in WHITE_SCALES:
            for b in self.flicker_scales:
                base = a * white_var + b * flicker + rest
                rows.append(base)
                self.labels.append((False, float(a), float(b), 0.0, 0.0))
                for tau, unit in zip(self.taus_s, units, strict=True):
                    for ratio in POWER_RATIOS:
                        sigma2 = ratio * reference / unit[0]
                        rows.append(base + sigma2 * unit)
                        self.labels.append((True, float(a), float(b), math.sqrt(sigma2), float(tau)))
        # the null rows first: each hypothesis's rows of the likelihood grid are then a view, not a copy
        order = np.argsort([label[0] for label in self.labels], kind="stable")
        self.labels = [self.labels[k] for k in order]
        spectra = np.vstack(rows)[order]
        self._weighted_inverse = self.counts / spectra
        self._log_sum = np.log(spectra) @ self.counts
        self._alternative = np.array([label[0] for label in self.labels])
        self._n_base = int(np.sum(~self._alternative))

    def best_alternative(self, band_values: np.ndarray) -> np.ndarray:
        """The grid maximum of the Markov alternative's log-likelihood for each column of band means."""
        alternative = self._alternative
        grid = -self._log_sum[alternative][:, None] - self._weighted_inverse[alternative] @ band_values
        return grid.max(axis=0)

    def band_means(self, x: np.ndarray) -> np.ndarray:
        """The periodogram of ``x`` (bin means) averaged over the test's bands."""
        return np.add.reduceat(periodogram(x), self.edges[:-1], axis=0) / (
            self.counts if np.ndim(x) == 1 else self.counts[:, None])

    def spectrum(self, a: float, b: float = 1.0, markov: tuple[float, float] | None = None) -> np.ndarray:
        """The model spectrum of bin means at the bands' mean frequencies."""
        s = a * self.white_var + b * self.flicker + self.rest
        if markov is not None:
            s = s + gm_bin_spectrum(markov[0], markov[1], self.width_s, self.omega)
        return s

    def loglik(self, band_values: np.ndarray, a: float, b: float = 1.0,
               markov: tuple[float, float] | None = None) -> float:
        s = self.spectrum(a, b, markov)
        return float(-np.sum(self.counts * (np.log(s) + band_values / s)))

    def expected_lr(self, sigma_dph: float, tau_s: float) -> float:
        """E[LR] when the Markov process is really there: 2·KL(H_markov ‖ H0), Whittle form."""
        ratio = self.spectrum(1.0, 1.0, (sigma_dph, tau_s)) / self.spectrum(1.0)
        return float(np.sum(self.counts * (ratio - 1.0 - np.log(ratio))))

    def null_bands(self, rng: np.random.Generator, n_null: int) -> np.ndarray:
        """Band means of effect-free periodograms: S0·Gamma(m, 1)/m per band, independent."""
        return self.spectrum(1.0)[:, None] * rng.gamma(self.counts[:, None], 1.0,
                                                       (self.counts.size, n_null)) / self.counts[:, None]

    def test(self, resid_bins: np.ndarray, rng: np.random.Generator, n_null: int) -> StochasticCandidate:
        """The Markov alternative on the data and on ``n_null`` simulated nulls, each refined alike."""
        data = self.band_means(resid_bins)
        values = np.column_stack([data, self.null_bands(rng, n_null)])
        grid = -self._log_sum[:, None] - self._weighted_inverse @ values
        n0 = self._n_base
        picks = (np.argmax(grid[:n0], axis=0), n0 + np.argmax(grid[n0:], axis=0))   # best null, alternative rows
        # every column refined alike, the data's and each effect-free draw's (whittle_null.py)
        ll0s, ll1s = self.refined_logliks(grid, values, picks)
        null_lr = np.maximum(2.0 * (ll1s[1:] - ll0s[1:]), 0.0)
        null_row, best_row = int(picks[0][0]), int(picks[1][0])
        _, a0, b0, sigma0, tau0 = self.labels[best_row]
        ll0 = max(self._refine(data, self.labels[null_row][1:3], None, float(grid[null_row, 0]))[-1], ll0s[0])
        a, b, sigma, tau, ll1 = self._refine(data, (a0, b0), (sigma0, tau0), float(grid[best_row, 0]))
        on_grid = np.maximum(2.0 * (grid[n0:, 1:].max(axis=0) - grid[:n0, 1:].max(axis=0)), 0.0)
        return StochasticCandidate(MARKOV, {"sigma_dph": sigma, "tau_s": tau},
                                   max(2.0 * (max(ll1, ll1s[0]) - ll0), 0.0), 2, null_lr, a,
                                   tau >= 0.99 * self.tau_bounds_s[1], b, on_grid)

    def refined_logliks(self, grid: np.ndarray, values: np.ndarray, picks: tuple[np.ndarray, np.ndarray]
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Each column's null and alternative log-likelihoods, refined from its best grid rows (``picks``).

        The same refinement for the data and every effect-free draw, so the threshold is
        the data statistic's own (the draws' were taken at the grid: whittle_null.py).
        """
        labels = np.array([label[1:] for label in self.labels])          # a, b, σ, τ per row
        free_b = self.flicker_scales.size > 1
        n_pick, a_pick = picks
        scales = [0, 1] if free_b else [0]
        null_start = np.log(labels[n_pick][:, scales]).T
        alt_start = np.vstack([np.log(labels[a_pick][:, scales]).T, 2.0 * np.log(labels[a_pick][:, 2]),
                               np.log(labels[a_pick][:, 3])])
        spectra = Spectra(self.white_var * np.ones_like(self.omega), self.flicker, self.rest, self.counts,
                          self.omega, self.width_s, (math.log(WHITE_SCALES[0]), math.log(WHITE_SCALES[-1])),
                          (math.log(self.flicker_scales[0]), math.log(self.flicker_scales[-1])) if free_b else None,
                          (math.log(self.tau_bounds_s[0]), math.log(self.tau_bounds_s[1])))
        columns = np.arange(grid.shape[1])
        return refined_logliks(spectra, values, null_start, alt_start, grid[n_pick, columns],
                               grid[a_pick, columns])

    def _refine(self, data: np.ndarray, scales: tuple[float, float], markov: tuple[float, float] | None,
                grid_best: float) -> tuple[float, ...]:
        """Continuous maximum near the best grid point (bounded Nelder–Mead in logs)."""
        with_flicker = self.flicker_scales.size > 1
        start = [scales[0]] + ([scales[1]] if with_flicker else []) + list(markov or ())
        bounds = [(math.log(WHITE_SCALES[0]), math.log(WHITE_SCALES[-1]))]
        if with_flicker:
            bounds.append((math.log(self.flicker_scales[0]), math.log(self.flicker_scales[-1])))
        if markov is not None:
            bounds += [(math.log(markov[0]) - 6.0, math.log(markov[0]) + 6.0),
                       tuple(math.log(t) for t in self.tau_bounds_s)]

        def unpack(x: np.ndarray) -> tuple[float, float, tuple[float, float] | None]:
            v = np.exp(x)
            b = float(v[1]) if with_flicker else 1.0
            rest = v[2:] if with_flicker else v[1:]
            return float(v[0]), b, (float(rest[0]), float(rest[1])) if markov is not None else None

        def negative(x: np.ndarray) -> float:
            a, b, m = unpack(x)
            return -self.loglik(data, a, b, m)

        result = optimize.minimize(negative, np.log(start), method="Nelder-Mead", bounds=bounds,
                                   options={"xatol": 1e-4, "fatol": 1e-3, "maxiter": 600})
        a, b, m = unpack(result.x if -result.fun >= grid_best else np.log(start))
        best = max(-float(result.fun), grid_best)
        return (a, b, *(m or ()), best)


#: Parts the record is split into for the stationarity test, and the grid of the process's
#: power in each part (relative to the whole-record fit) the likelihood is profiled on.
STATIONARITY_PARTS = 2
_POWER_GRID = np.geomspace(1e-3, 1e3, 61)


@dataclass(frozen=True)
class Stationarity:
    """The Markov process's power fitted in each part of the record, and whether it is one process.

    ``statistic`` is twice the log-likelihood gain of a separate power per part
    over one common power (τ, white and flicker levels held at the whole-record
    fit); ``limit`` its (1 − α) point on records simulated from the common fit.
    """

    power_ratio: tuple[float, ...]     # fitted σ² per part / the whole record's σ²
    statistic: float
    limit: float

    @property
    def stationary(self) -> bool:
        return self.statistic <= self.limit


def stationarity_test(noise: NoiseModel, resid_bins: np.ndarray, bins: Bins, fs_hz: float,
                      markov: StochasticCandidate, rng: np.random.Generator, n_null: int,
                      alpha: float) -> Stationarity:
    """Whether the fitted Markov process is the same stationary process in every part of the record.

    A Gauss–Markov process with a long τ imitates almost any slow curve over one
    record (a bias accelerating with time was named markov_bias at 1.0); a
    deterministic shape is not stationary: its power sits where the shape bends.
    The test is Whittle's again, per part: the process's power is profiled
    separately in each part and jointly, and the gain of the separate fit is
    held against the same gain on parts simulated from the common fit (band
    means S·Gamma(m, 1)/m, independent between parts), so its level is α.
    """
    sigma2, tau = markov.params["sigma_dph"] ** 2, markov.params["tau_s"]
    n_part = bins.n_bins // STATIONARITY_PARTS
    grids = []
    for k in range(STATIONARITY_PARTS):
        part = Bins(bins.samples_per_bin, n_part, bins.centre_s[k * n_part:(k + 1) * n_part], bins.width_s)
        test = WhittleTest(noise, part, fs_hz)
        base = test.spectrum(markov.white_scale, markov.flicker_scale)
        unit = gm_bin_spectrum(1.0, tau, test.width_s, test.omega)
        spectra = base[:, None] + sigma2 * _POWER_GRID[None, :] * unit[:, None]     # bands × grid
        common = base + sigma2 * unit
        draws = common[:, None] * rng.gamma(test.counts[:, None], 1.0, (test.counts.size, n_null)) / \
            test.counts[:, None]
        values = np.column_stack([test.band_means(resid_bins[k * n_part:(k + 1) * n_part]), draws])
        # log-likelihood of every grid power on the data (column 0) and each null draw
        weighted = (test.counts[:, None] / spectra).T @ values
        grids.append(-(np.log(spectra).T @ test.counts)[:, None] - weighted)          # grid × (1 + n_null)
    separate = sum(g.max(axis=0) for g in grids)
    joint = np.sum(grids, axis=0).max(axis=0)
    stat = 2.0 * (separate - joint)
    ratios = tuple(float(_POWER_GRID[int(np.argmax(g[:, 0]))]) for g in grids)
    return Stationarity(ratios, float(stat[0]), order_statistic_quantile(stat[1:], 1.0 - alpha))
