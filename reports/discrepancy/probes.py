"""Out-of-catalogue probes: generic shapes that compete with the catalogue before anything is named.

A catalogue effect is named only if nothing generic explains the data
clearly better; otherwise structure outside the catalogue would be named
after its nearest neighbour (a scale-factor step first drew thermal_lag and
sf_temp_quadratic at probability 1.0 before ending unexplained). The probes:

* a **bias step** at any of ``POSITIONS`` times (deg/h);
* a **scale-factor step** at any of those times (ppm: a rate-proportional
  change, ω·1e-6·ppm in deg/s);
* a **slow sinusoid** of unknown period, from half the record down to eight
  bins (a cos/sin pair per frequency, deg/h). At least two periods must be in
  the record: less is a bump, not a periodicity, and a bump is what two wiggles
  of a slow Gauss–Markov bias look like (a sinusoid of period 1.1 record lengths
  took the place of a τ = 1000 s Markov bias on a 1-hour record).

Each is scored like a catalogue effect (the Δχ² of its columns after the
refitted base and the whitening), its threshold is the (1 − α) point of its
best score on the same simulated effect-free data, and it competes with the
best catalogue effect after the search penalty of its position or frequency
grid (2 ln M): a generic shape is always at least as flexible as a named one
and must win by more than what its search alone would buy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy import stats

from gyrocal.reports.discrepancy.scoring import (
    Fit,
    Whitener,
    order_statistic_quantile,
    score_from_delta,
)
from gyrocal.reports.discrepancy.segments import Bins

#: Number of step positions a step probe tries.
POSITIONS = 150
#: Most frequencies the slow-sinusoid probe tries.
MAX_FREQUENCIES = 200


class ProbeKind(Enum):
    BIAS_STEP = "bias step"
    SF_STEP = "scale-factor step"
    SLOW_SINE = "slow sinusoid"


@dataclass(frozen=True)
class Probe:
    """The best instance of one generic shape, and whether it stands out of the noise."""

    kind: ProbeKind
    where: float          # step time (s from the record start) or sinusoid frequency (Hz)
    size: float           # deg/h (bias step, sinusoid amplitude) or ppm (scale-factor step)
    delta_chi2: float
    dof: int
    threshold: float
    n_candidates: int
    phase_rad: float = 0.0   # slow sinusoid: size·cos(2π·where·t − phase)

    @property
    def score(self) -> float:
        return score_from_delta(self.delta_chi2, self.dof)

    @property
    def significant(self) -> bool:
        return self.score > self.threshold

    @property
    def penalised_delta(self) -> float:
        """Δχ² less what searching its grid buys on noise alone (2 ln M)."""
        return self.delta_chi2 - 2.0 * math.log(max(self.n_candidates, 1))

    @property
    def time_s(self) -> float:
        return self.where

    @property
    def size_dph(self) -> float:
        return self.size

    def signal_dph(self, t_s: np.ndarray, rate_dps: np.ndarray) -> np.ndarray:
        """The fitted probe at times ``t_s`` (table rate ``rate_dps``), deg/h."""
        if self.kind is ProbeKind.BIAS_STEP:
            return np.where(t_s >= self.where, self.size, 0.0)
        if self.kind is ProbeKind.SF_STEP:
            return np.where(t_s >= self.where, self.size * 1e-6 * 3600.0 * rate_dps, 0.0)
        return self.size * np.cos(2.0 * math.pi * self.where * t_s - self.phase_rad)

    def describe(self) -> str:
        if self.kind is ProbeKind.BIAS_STEP:
            return f"a bias step of {self.size:+.3g} deg/h near t = {self.where:.0f} s"
        if self.kind is ProbeKind.SF_STEP:
            return f"a scale-factor step of {self.size:+.3g} ppm near t = {self.where:.0f} s"
        return f"a slow sinusoid of {abs(self.size):.3g} deg/h, period {1.0 / self.where:.0f} s"


def step_columns(n_bins: int, positions: np.ndarray) -> np.ndarray:
    """Unit bias steps starting at each bin position."""
    return (np.arange(n_bins)[:, None] >= positions[None, :]).astype(float)


def _null_scores(gains: np.ndarray, dof: int) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return -stats.chi2.logsf(gains, dof) / math.log(10.0)


def _single_column_probe(kind: ProbeKind, columns: np.ndarray, where: np.ndarray, unit: float,
                         fit: Fit, whitener: Whitener, z: np.ndarray, alpha: float) -> Probe:
    ws = whitener.white(columns)
    perp = ws - fit.basis @ (fit.basis.T @ ws)
    norms = np.linalg.norm(perp, axis=0)
    usable = norms > 1e-9 * max(norms.max(), 1e-300)
    q = perp[:, usable] / norms[usable]
    proj = q.T @ fit.white_resid
    k = int(np.argmax(proj**2))
    null = np.max((q.T @ z) ** 2, axis=0)
    threshold = order_statistic_quantile(_null_scores(null, 1), 1.0 - alpha)
    return Probe(kind, float(where[usable][k]), float(proj[k] / norms[usable][k]) * unit,
                 float(proj[k] ** 2), 1, threshold, int(usable.sum()))


def bias_step_probe(fit: Fit, whitener: Whitener, bins: Bins, z: np.ndarray, alpha: float) -> Probe:
    n = bins.n_bins
    positions = np.unique(np.linspace(0.02 * n, 0.98 * n, POSITIONS).astype(int))
    return _single_column_probe(ProbeKind.BIAS_STEP, step_columns(n, positions),
                                bins.centre_s[positions] - bins.width_s / 2, 1.0, fit, whitener, z, alpha)


def sf_step_probe(fit: Fit, whitener: Whitener, bins: Bins, rate_bins_dps: np.ndarray, z: np.ndarray,
                  alpha: float) -> Probe | None:
    """None when the table never turned (a scale-factor step leaves no trace)."""
    if not np.any(np.abs(rate_bins_dps) > 0):
        return None
    n = bins.n_bins
    positions = np.unique(np.linspace(0.02 * n, 0.98 * n, POSITIONS).astype(int))
    ppm_dph = rate_bins_dps * 3600.0 * 1e-6          # deg/h per ppm at each bin's rate
    columns = step_columns(n, positions) * ppm_dph[:, None]
    return _single_column_probe(ProbeKind.SF_STEP, columns, bins.centre_s[positions] - bins.width_s / 2,
                                1.0, fit, whitener, z, alpha)


def slow_sine_probe(fit: Fit, whitener: Whitener, bins: Bins, z: np.ndarray, alpha: float) -> Probe:
    duration_s = bins.n_bins * bins.width_s
    f_lo, f_hi = 2.0 / duration_s, 1.0 / (8.0 * bins.width_s)
    count = int(min(MAX_FREQUENCIES, max(2, (f_hi - f_lo) * duration_s * 2)))
    freqs = np.geomspace(f_lo, f_hi, count)
    phase = 2.0 * math.pi * bins.centre_s[:, None] * freqs[None, :]
    pieces = []
    for part in (np.cos(phase), np.sin(phase)):
        w = whitener.white(part)
        pieces.append(w - fit.basis @ (fit.basis.T @ w))
    a, b = pieces
    g11, g12, g22 = np.sum(a * a, 0), np.sum(a * b, 0), np.sum(b * b, 0)
    det = g11 * g22 - g12 * g12
    usable = det > 1e-9 * max(float(np.max(det)), 1e-300)

    def gains(r: np.ndarray) -> np.ndarray:
        u, v = a.T @ r, b.T @ r
        out = (g22[:, None] * u * u - 2 * g12[:, None] * u * v + g11[:, None] * v * v) / np.where(
            usable, det, 1.0)[:, None]
        return np.where(usable[:, None], out, 0.0)

    data = gains(fit.white_resid[:, None])[:, 0]
    k = int(np.argmax(data))
    u, v = float(a[:, k] @ fit.white_resid), float(b[:, k] @ fit.white_resid)
    coef = np.linalg.solve([[g11[k], g12[k]], [g12[k], g22[k]]], [u, v]) if usable[k] else np.zeros(2)
    null = np.max(gains(z), axis=0)
    threshold = order_statistic_quantile(_null_scores(null, 2), 1.0 - alpha)
    return Probe(ProbeKind.SLOW_SINE, float(freqs[k]), float(math.hypot(*coef)), float(data[k]), 2,
                 threshold, int(usable.sum()), float(math.atan2(coef[1], coef[0])))


def all_probes(fit: Fit, whitener: Whitener, bins: Bins, rate_bins_dps: np.ndarray, z: np.ndarray,
               alpha: float) -> list[Probe]:
    probes = [bias_step_probe(fit, whitener, bins, z, alpha),
              sf_step_probe(fit, whitener, bins, rate_bins_dps, z, alpha),
              slow_sine_probe(fit, whitener, bins, z, alpha)]
    return [p for p in probes if p is not None]


def strongest(probes: list[Probe]) -> Probe | None:
    """The significant probe with the largest penalised gain, if any is significant."""
    significant = [p for p in probes if p.significant]
    return max(significant, key=lambda p: p.penalised_delta) if significant else None
