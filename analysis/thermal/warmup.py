"""Warm-up and turn-on-to-turn-on repeatability (IEEE Std 952 / IEEE Std 1431).

Warm-up: after power-on the bias settles as b(t) = b∞ + A·e^(−t/τ) (the catalogue's
``warmup_transient``). The record, logged from power-on, is reduced to bin means (so the
fit handles minutes of 2 kHz data and the white noise averages down), and the three
parameters are fitted by least squares (scipy ``curve_fit``) with their covariance scaled
by the residual variance (GUM type A). The time until the bias stays within ±band of its
settled value follows from the fit, t_band = τ·ln(|A|/band), with its uncertainty
propagated from the covariance; the measured time (the last bin outside the band) is
reported beside it.

Repeatability: the biases of N power cycles after the same settling time; their standard
deviation s, with u(s) = s/√(2(N−1)) (the standard deviation of a normal sample's s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit

COVERAGE_K = 2.0


@dataclass(frozen=True)
class WarmupFit:
    settled_dph: float
    amplitude_dph: float
    tau_s: float
    u_settled_dph: float
    u_amplitude_dph: float
    u_tau_s: float
    cov: np.ndarray

    def time_to_band_s(self, band_dph: float) -> tuple[float, float]:
        """(t, u(t)) when |A|·e^(−t/τ) falls to ``band_dph``; 0 s if it starts inside."""
        ratio = abs(self.amplitude_dph) / band_dph
        if ratio <= 1.0:
            return 0.0, 0.0
        t = self.tau_s * math.log(ratio)
        # ∂t/∂A = τ/A, ∂t/∂τ = ln(|A|/band); the covariance of (A, τ) is cov[1:, 1:]
        grad = np.array([self.tau_s / self.amplitude_dph, math.log(ratio)])
        return t, math.sqrt(float(grad @ self.cov[1:, 1:] @ grad))


def bin_means(t_s: np.ndarray, bias_dph: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre times and means of consecutive bins of ``bin_s`` (a partial last bin dropped)."""
    per_bin = max(1, int(round(bin_s / float(np.median(np.diff(t_s))))))
    count = t_s.size // per_bin
    if count < 4:
        raise ValueError(f"{t_s.size} samples make {count} bins of {bin_s:g} s; a fit needs 4")
    shape = (count, per_bin)
    return (t_s[:count * per_bin].reshape(shape).mean(axis=1),
            bias_dph[:count * per_bin].reshape(shape).mean(axis=1))


def _transient(t: np.ndarray, settled: float, amplitude: float, tau: float) -> np.ndarray:
    return settled + amplitude * np.exp(-t / tau)


def fit_warmup(t_s: np.ndarray, bias_dph: np.ndarray, bin_s: float = 1.0) -> WarmupFit:
    """Fit b∞ + A·e^(−t/τ) to a record logged from power-on (``t_s`` from power-on)."""
    centres, means = bin_means(t_s, bias_dph, bin_s)
    settled0 = float(np.median(means[-max(1, means.size // 5):]))
    amplitude0 = float(means[0] - settled0)
    # τ guess: when the excess first falls below 1/e of its start
    excess = np.abs(means - settled0)
    below = np.flatnonzero(excess < abs(amplitude0) / math.e)
    tau0 = float(centres[below[0]]) if below.size else float(centres[-1]) / 3.0
    params, cov = curve_fit(_transient, centres, means, p0=(settled0, amplitude0, max(tau0, bin_s)),
                            maxfev=10000)
    if not np.all(np.isfinite(cov)):
        raise ValueError("the warm-up fit is not determined (no transient in the record?)")
    u = np.sqrt(np.diag(cov))
    return WarmupFit(float(params[0]), float(params[1]), float(params[2]),
                     float(u[0]), float(u[1]), float(u[2]), cov)


def measured_time_to_band_s(t_s: np.ndarray, bias_dph: np.ndarray, settled_dph: float,
                            band_dph: float, bin_s: float) -> float:
    """The end of the last bin whose mean lies outside ±band of the settled value."""
    centres, means = bin_means(t_s, bias_dph, bin_s)
    outside = np.flatnonzero(np.abs(means - settled_dph) > band_dph)
    return 0.0 if outside.size == 0 else float(centres[outside[-1]] + 0.5 * bin_s)


@dataclass(frozen=True)
class Repeatability:
    std_dph: float
    u_std_dph: float
    n: int
    biases_dph: tuple[float, ...]


def turn_on_repeatability(biases_dph: list[float]) -> Repeatability:
    """Standard deviation of the settled biases of N power cycles, and its u from N."""
    n = len(biases_dph)
    if n < 2:
        raise ValueError("turn-on repeatability needs at least two power cycles")
    std = float(np.std(biases_dph, ddof=1))
    return Repeatability(std, std / math.sqrt(2.0 * (n - 1)), n, tuple(biases_dph))
