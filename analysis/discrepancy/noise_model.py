"""The noise model the discrepancy likelihood is built on, and its estimate from quiet segments.

Every score in the workflow is a likelihood gain after whitening by this
model, so it must describe the gyro's own noise and nothing else. It is
therefore estimated from quiet segments (steady chamber, table still or at a
constant rate), where a missing deterministic effect barely shows, and not
from the whole residual, which would soak the missing effect up as "noise".

Within a quiet segment of a few minutes the white part (N, Q) and a Markov
hump are well determined, but the flicker floor B and the rate random walk K
often are not (their Allan signature needs τ longer than the segments): for
those the estimate is used only when its 68 % interval is narrow, otherwise
the model file's value is kept. The covariance of bin means is exact for the
terms as the project's simulator draws them (white, Gauss–Markov bank for
flicker, Markov, random walk, ramp), which is what makes the simulated
threshold calibration meaningful.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.linalg import toeplitz

from gyrocal.analysis.allan.deviation import log_spaced_m, overlapping_adev
from gyrocal.analysis.allan.noise_fit import NoiseFit, fit_noise_terms
from gyrocal.models.allan_theory import noise_avar
from gyrocal.models.gyro_model import GyroModel, NoiseParams
from gyrocal.models.noise import flicker_bank

#: A Markov term is accepted when it lowers the Allan-fit χ² by more than this and its
#: peak (1.89·T) sits inside the curve with a factor 4 to spare on both sides. The
#: noise fit's own "auto" rule is tuned for long static records; on the few minutes of
#: quiet data a procedure has it misses clear humps. Measured on the scenario profiles
#: (effect-free, 6 seeds): drops of 0 to 12; σ = 0.6 deg/h, T = 8 s: about 100.
MARKOV_MIN_DELTA_CHI2 = 30.0
MARKOV_PEAK_MARGIN = 4.0

#: A B or K estimate from quiet segments replaces the model file's value only
#: when its 68 % half-interval is below this fraction of the larger of the two.
INFORMATIVE_HALF_WIDTH = 0.3


@dataclass(frozen=True)
class NoiseModel:
    """IEEE 952 terms (spec units) plus an optional first-order Markov term."""

    arw_deg_per_rth: float = 0.0
    bias_instability_dph: float = 0.0
    rrw_deg_per_h_rth: float = 0.0
    quantization_arcsec: float = 0.0
    rate_ramp_dph_per_h: float = 0.0
    markov_sigma_dph: float = 0.0
    markov_tau_s: float = 0.0

    @classmethod
    def of_model(cls, model: GyroModel) -> NoiseModel:
        """The model file's noise section plus its markov_bias effect, if any."""
        n = model.noise
        markov = model.effect("markov_bias")
        return cls(
            n.arw_deg_per_rth, n.bias_instability_dph, n.rrw_deg_per_h_rth,
            n.quantization_arcsec, n.rate_ramp_dph_per_h,
            0.0 if markov is None else markov["sigma_dph"],
            0.0 if markov is None else markov["tau_s"],
        )

    @property
    def has_markov(self) -> bool:
        return self.markov_sigma_dph > 0 and self.markov_tau_s > 0

    def noise_params(self) -> NoiseParams:
        return NoiseParams(self.quantization_arcsec, self.arw_deg_per_rth,
                           self.bias_instability_dph, self.rrw_deg_per_h_rth,
                           self.rate_ramp_dph_per_h)

    def markov_tuple(self) -> tuple[float, float] | None:
        return (self.markov_sigma_dph, self.markov_tau_s) if self.has_markov else None

    def _markov_processes(self) -> list[tuple[float, float]]:
        """(sigma_dph, tau_s) of every Gauss–Markov process: flicker bank + Markov."""
        processes: list[tuple[float, float]] = []
        if self.bias_instability_dph > 0:
            taus, sigmas = flicker_bank(self.bias_instability_dph)
            processes.extend(zip(sigmas.tolist(), taus.tolist(), strict=True))
        if self.has_markov:
            processes.append((self.markov_sigma_dph, self.markov_tau_s))
        return processes

    def white_sigma_dph(self, fs_hz: float) -> float:
        """Per-sample std of the white-rate part at ``fs_hz``."""
        return 60.0 * self.arw_deg_per_rth * math.sqrt(fs_hz)

    def allan_deviation_dph(self, tau_s) -> np.ndarray:
        """The model's Allan deviation (deg/h), the reference the residual's curve is held against."""
        avar = noise_avar(tau_s, self.quantization_arcsec, self.arw_deg_per_rth,
                          self.bias_instability_dph, self.rrw_deg_per_h_rth,
                          self.rate_ramp_dph_per_h, markov=self.markov_tuple())
        return np.sqrt(avar)

    def psd_two_sided(self, f_hz, fs_hz: float) -> np.ndarray:
        """Two-sided PSD of the sampled rate noise, (deg/h)²/Hz (white level 3600·N²)."""
        f = np.asarray(f_hz, dtype=float)
        psd = np.full(f.shape, 3600.0 * self.arw_deg_per_rth**2)
        for sigma, tau in self._markov_processes():
            psd = psd + 2.0 * sigma**2 * tau / (1.0 + (2.0 * math.pi * f * tau) ** 2)
        if self.quantization_arcsec > 0:
            psd = psd + self.quantization_arcsec**2 * fs_hz * 4.0 * np.sin(math.pi * f / fs_hz) ** 2
        if self.rrw_deg_per_h_rth > 0:
            with np.errstate(divide="ignore"):
                psd = psd + (self.rrw_deg_per_h_rth / 60.0) ** 2 / (2.0 * math.pi * f) ** 2
        return psd

    def bin_covariance(self, centre_s: np.ndarray, width_s: float, samples_per_bin: int,
                       fs_hz: float) -> np.ndarray:
        """Covariance (deg/h)² of the means of consecutive bins of ``samples_per_bin`` samples.

        ``centre_s`` are the bin centres measured from the record start. Each
        Gauss–Markov process (σ, T) averaged over bins of width D has
        var = 2σ²(T/D)[1 − (T/D)(1 − e^{−D/T})] and, for bins Δ ≥ D apart,
        cov = σ²(T/D)²(1 − e^{−D/T})²·e^{−(Δ−D)/T}: exact, so a process much
        faster than a bin is correctly seen as white. Uniform bins use a
        Toeplitz construction; gaps (run folders) the dense time differences.
        """
        t = np.asarray(centre_s, dtype=float)
        n = t.size
        d = float(width_s)
        diffs = np.diff(t)
        uniform = n < 2 or np.ptp(diffs) <= 1e-6 * d
        lag = (np.arange(n) * (diffs[0] if n > 1 else d)) if uniform else None
        dense = None if uniform else np.abs(t[:, None] - t[None, :])

        white_var = 3600.0 * self.arw_deg_per_rth**2 * fs_hz / samples_per_bin
        column = np.zeros(n)
        cov = None if uniform else np.zeros((n, n))

        def add(acov_of_lag) -> None:
            nonlocal column, cov
            if uniform:
                column = column + acov_of_lag(lag)
            else:
                cov = cov + acov_of_lag(dense)

        for sigma, tau in self._markov_processes():
            x = d / tau
            one_minus = -math.expm1(-x)
            var = 2.0 * sigma**2 / x * (1.0 - one_minus / x)
            off = sigma**2 * (one_minus / x) ** 2

            def acov(delta, var=var, off=off, tau=tau):
                out = off * np.exp(-np.maximum(delta - d, 0.0) / tau)
                return np.where(delta < 0.5 * d, var, out)

            add(acov)
        if self.quantization_arcsec > 0:
            q2 = (self.quantization_arcsec / d) ** 2

            def acov_q(delta, q2=q2):
                return np.where(delta < 0.5 * d, 2.0 * q2, np.where(delta < 1.5 * d, -q2, 0.0))

            add(acov_q)
        out = toeplitz(column) if uniform else cov
        out[np.diag_indices(n)] += white_var
        if self.rrw_deg_per_h_rth > 0:
            # a random walk from 0 at the record start: cov = q·min(t_i, t_j), minus qD/6 on
            # the diagonal for the averaging within a bin
            q = (self.rrw_deg_per_h_rth / 60.0) ** 2
            out += q * np.minimum(t[:, None], t[None, :])
            out[np.diag_indices(n)] -= q * d / 6.0
        if self.rate_ramp_dph_per_h > 0:
            slope = self.rate_ramp_dph_per_h / 3600.0
            out += slope**2 * np.outer(t, t)
        return out


@dataclass(frozen=True)
class NoiseEstimate:
    """The noise model used for the likelihood, and how it was obtained."""

    model: NoiseModel
    fit: NoiseFit | None
    tau_s: np.ndarray            # quiet-segment Allan curve the fit saw
    adev_dph: np.ndarray
    quiet_seconds: float
    source: str                  # what came from the data and what from the model file


def _white_edf(n: int, m: np.ndarray) -> np.ndarray:
    """EDF of an overlapping AVAR estimate for white rate noise (Howe, Allan & Barnes)."""
    return (3.0 * (n - 1) / (2.0 * m) - 2.0 * (n - 2) / n) * 4.0 * m**2 / (4.0 * m**2 + 5.0)


def quiet_allan(residual_dph: np.ndarray, fs_hz: float, quiet: list[slice]):
    """Allan curve pooled over quiet segments: AVAR weighted by terms, EDFs summed.

    Pooling per segment (never across a join) keeps the step between two
    segments' levels out of the noise estimate. The EDFs are the white-rate
    ones (the short-τ points that carry the weight are white-dominated).
    """
    lengths = [s.stop - s.start for s in quiet]
    longest = max(lengths)
    m_grid = log_spaced_m(longest, count=40)
    weighted = np.zeros(m_grid.size)
    terms = np.zeros(m_grid.size)
    edf = np.zeros(m_grid.size)
    for piece in quiet:
        data = residual_dph[piece]
        usable = m_grid[4 * m_grid <= data.size]
        if usable.size == 0:
            continue
        result = overlapping_adev(data, fs_hz, m=usable, confidence=None)
        k = np.searchsorted(m_grid, result.m)
        weighted[k] += result.adev**2 * result.n_terms
        terms[k] += result.n_terms
        edf[k] += np.maximum(_white_edf(data.size, result.m.astype(float)), 1.0)
    keep = terms > 0
    tau = m_grid[keep] / fs_hz
    adev = np.sqrt(weighted[keep] / terms[keep])
    return tau, adev, edf[keep]


def estimate_noise(residual_dph: np.ndarray, fs_hz: float, quiet: list[slice],
                   prior: NoiseModel, allow_markov: bool = True,
                   long_terms: bool = True, markov_min_tau_s: float = 0.0) -> NoiseEstimate:
    """Fit the noise terms on the quiet segments of ``residual_dph`` (deg/h, full rate).

    ``markov_min_tau_s`` refuses a Markov term faster than that (a pulse-counting
    gyro's white noise came back as N = 0 plus a 0.04 s "Markov" process).
    ``long_terms=False`` keeps the model file's B and K whatever the quiet
    segments say: the discrepancy workflow judges slow noise over the whole
    record instead (stochastic.py), and a B taken from a few minutes of data
    absorbs a Markov bias into the noise model, where nothing can name it.

    Falls back to ``prior`` (the model file) when there is too little quiet
    data for an Allan curve (< 2 minutes or < 8 τ points).
    """
    quiet = [s for s in quiet if s.stop - s.start >= 64]
    seconds = sum(s.stop - s.start for s in quiet) / fs_hz
    if seconds < 120.0:
        return NoiseEstimate(prior, None, np.zeros(0), np.zeros(0), seconds,
                             "model file (too little quiet data)")
    tau, adev, edf = quiet_allan(residual_dph, fs_hz, quiet)
    if tau.size < 8:
        return NoiseEstimate(prior, None, tau, adev, seconds, "model file (Allan curve too short)")
    fit = fit_noise_terms(tau, adev, edf, markov=False)
    if allow_markov:
        with_markov = fit_noise_terms(tau, adev, edf, markov=True)
        peak = with_markov.markov.tau_peak_s
        if (fit.chi2 - with_markov.chi2 > MARKOV_MIN_DELTA_CHI2
                and MARKOV_PEAK_MARGIN * tau[0] < peak < tau[-1] / MARKOV_PEAK_MARGIN
                and with_markov.markov.tau_s.value >= markov_min_tau_s
                and with_markov.markov.sigma_dph.value > 0):
            fit = with_markov
    chosen = replace(prior, arw_deg_per_rth=fit.N_deg_per_rth.value,
                     quantization_arcsec=fit.Q_arcsec.value)
    source = ["N, Q from quiet segments"]
    for term, key in ((fit.B_dph, "bias_instability_dph"), (fit.K_dph_per_rth, "rrw_deg_per_h_rth")):
        if not long_terms:
            source.append(f"{key} from the model file (slow noise is judged over the whole record)")
            continue
        prior_value = getattr(prior, key)
        scale = max(term.value, prior_value)
        if scale > 0 and 0.5 * (term.hi - term.lo) < INFORMATIVE_HALF_WIDTH * scale:
            chosen = replace(chosen, **{key: term.value})
            source.append(f"{key} from quiet segments")
        else:
            source.append(f"{key} from the model file (not observable in the quiet segments)")
    if fit.markov is not None and allow_markov:
        chosen = replace(chosen, markov_sigma_dph=fit.markov.sigma_dph.value,
                         markov_tau_s=fit.markov.tau_s.value)
        source.append("Markov term from quiet segments")
    return NoiseEstimate(chosen, fit, tau, adev, seconds, "; ".join(source))
