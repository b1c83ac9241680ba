"""A narrow-band random bias (a peaked spectrum): neither a spectral line nor a Markov bias.

A controller hunting around its set point, a thermal loop ringing, a mount
resonance driven by the room: a second-order Gauss–Markov process (a damped
oscillator driven by noise), whose spectrum peaks at f0 with a width f0/Q.
The catalogue reads random excess power as a Markov bias, whose spectrum is a
Lorentzian (flat, then f⁻²: no peak), and periodic power as one fixed line
(all of it in one frequency). On the fourth held-out set a narrow-band random
bias near a 4-min period was neither named nor called unexplained on two of its
three profiles (4 of 4 runs silent); on our own cases (P1, Q1, 10σ) the search
named markov_bias at 1.0 in two of four runs and read the rest as "a slow
sinusoid" (a deterministic probe).

The test (after the last refit, on the one-second bin means of the full-rate
residual, by Whittle's likelihood as stochastic.py has it): the residual's
band-averaged periodogram under

* the catalogue's readings: the noise model (white and flicker at the scales
  the catalogue's best reading fitted), that plus a Markov bias (σ, τ on the
  Markov test's grid), and that plus a free level in any one band (a line);
* the resonant alternative: the noise model plus a second-order process,
  S ∝ 1/((f0² − f²)² + (f·f0/Q)²), on a grid of f0 (three cycles per record up
  to a quarter of the bins' rate), Q (1.5 to 8: a peak, narrower than a
  Lorentzian can be and wider than a line) and its power.

The statistic is the resonant log-likelihood less the best catalogue one;
its limit is the (1 − ``NARROW_ALPHA``) point of the same statistic on draws of
the best catalogue reading (band means S·Gamma(m, 1)/m, as the Markov test's
nulls), from their own generator, so a true Markov bias or a true line is
refused in about 0.5 % of records and the rest of a run draws what it drew
before. When it fires the result is ``unexplained``, ``where`` describes the
band ("a random bias in a narrow band around 0.0042 Hz (Q ≈ 3) …"), and a named
markov_bias keeps only ``1 − real_probability(score, limit)`` of its
probability, the score being the statistic's −log10 tail on those draws (the
adequacy test's odds rule).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.result import DiscrepancyResult
from gyrocal.analysis.discrepancy.scoring import Fit, order_statistic_quantile
from gyrocal.analysis.discrepancy.stochastic import (
    MARKOV,
    POWER_RATIOS,
    WHITE_SCALES,
    WhittleTest,
    fine_bins,
)

#: Level of the test: a true Markov bias, line or effect-free record is called narrow-band this often.
NARROW_ALPHA = 0.005
#: Draws of the catalogue's best reading the limit is read from, and their generator's seed.
NARROW_DRAWS = 400
NARROW_SEED = 2930
#: The resonance's quality factors (a peak: above the Lorentzian's limit, below a line's) and
#: the number of centre frequencies, from three cycles per record to a quarter of the bins' rate.
QS = np.array([1.5, 2.0, 3.0, 5.0, 8.0])
N_CENTRES = 48
MIN_CYCLES = 3.0
TOP_FRACTION = 0.25


@dataclass(frozen=True)
class NarrowBand:
    """The best resonant reading and the test's figures."""

    f0_hz: float
    q: float
    sigma_dph: float
    statistic: float           # resonant log-likelihood − best catalogue one
    limit: float               # its (1 − NARROW_ALPHA) point on draws of that reading
    tail: float                # fraction of the draws at or above the statistic (one added)
    catalogue: str             # which catalogue reading was best

    @property
    def fires(self) -> bool:
        return self.statistic > self.limit

    @property
    def score(self) -> float:
        return -math.log10(self.tail)

    @property
    def whole_account(self) -> float:
        return 1.0 - real_probability(self.score, -math.log10(NARROW_ALPHA))

    def describe(self) -> str:
        return (f"a random bias in a narrow band around {self.f0_hz:.2g} Hz (Q ≈ {self.q:.2g}; period "
                f"{1.0 / self.f0_hz:.0f} s, σ ≈ {self.sigma_dph:.3g} deg/h): its spectrum peaks there, which "
                f"neither a line nor a Markov bias fits (Whittle log-likelihood +{self.statistic:.1f} over "
                f"the best of them, {self.catalogue}; limit {self.limit:.1f} at α = {NARROW_ALPHA:g} on draws "
                "of that reading)")


def _resonance(test: WhittleTest, f0_hz: float, q: float) -> np.ndarray:
    """A second-order process's spectrum of bin means at the test's bands, peak 1 (bin averaging as sinc²)."""
    f = test.omega / (2.0 * math.pi * test.width_s)
    s = (f0_hz**4 / q**2) / ((f0_hz**2 - f**2) ** 2 + (f * f0_hz / q) ** 2)
    return s * np.sinc(f * test.width_s) ** 2


def _readings(test: WhittleTest, a: float, b: float) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float, float]]]:
    """Spectra of the catalogue's readings (null, Markov) and of the resonant one, at scales (a, b)."""
    base = test.spectrum(a, b)
    reference = float(np.median(base))
    catalogue = [base] + [base + ratio * reference * unit for unit in _markov_units(test) for ratio in POWER_RATIOS]
    top = TOP_FRACTION / test.width_s
    centres = np.geomspace(MIN_CYCLES / test.duration_s, top, N_CENTRES) if top > MIN_CYCLES / test.duration_s \
        else np.zeros(0)
    resonant, labels = [], []
    for f0 in centres:
        for q in QS:
            unit = _resonance(test, float(f0), float(q))
            for ratio in POWER_RATIOS:
                resonant.append(base + ratio * reference * unit)
                labels.append((float(f0), float(q), float(ratio * reference)))
    return np.vstack(catalogue), np.vstack(resonant) if resonant else np.zeros((0, base.size)), labels


def _scales(test: WhittleTest, data: np.ndarray) -> tuple[float, float]:
    """The white and flicker scales of the catalogue's best reading (null or Markov) of the data."""
    best, scales = -math.inf, (1.0, 1.0)
    for a in WHITE_SCALES:
        for b in test.flicker_scales:
            base = test.spectrum(float(a), float(b))
            rows = [base] + [base + ratio * float(np.median(base)) * unit for unit in _markov_units(test)
                             for ratio in POWER_RATIOS]
            value = float(_loglik(np.vstack(rows), test.counts, data[:, None]).max())
            if value > best:
                best, scales = value, (float(a), float(b))
    return scales


def _markov_units(test: WhittleTest) -> list[np.ndarray]:
    """The Markov grid's spectra of bin means, each divided by its lowest band's value."""
    units = []
    for tau in test.taus_s:
        unit = test.spectrum(0.0, 0.0, (1.0, float(tau))) - test.spectrum(0.0, 0.0)
        units.append(unit / unit[0])
    return units


def _loglik(spectra: np.ndarray, counts: np.ndarray, values: np.ndarray) -> np.ndarray:
    return -(np.log(spectra) @ counts)[:, None] - (counts / spectra) @ values


def _line_gain(base: np.ndarray, counts: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The best one-band free level over ``base`` (a line's reading), per column: max_j m_j·(r − 1 − ln r)."""
    r = np.maximum(values / base[:, None], 1.0)
    return (counts[:, None] * (r - 1.0 - np.log(r))).max(axis=0)


def narrow_band_test(test: WhittleTest, resid_bins: np.ndarray) -> NarrowBand | None:
    """The resonant reading against the catalogue's best on the data and on its draws (None: no band to search)."""
    data = test.band_means(resid_bins)
    a, b = _scales(test, data)
    catalogue, resonant, labels = _readings(test, a, b)
    if not labels:
        return None
    counts = test.counts
    cat = _loglik(catalogue, counts, data[:, None])[:, 0]
    best_cat = int(np.argmax(cat))
    line = cat[0] + _line_gain(catalogue[0], counts, data[:, None])[0]
    # named after a line only when its free band beats the rest by more than its search over the bands
    # (the statistic holds the line's gain unpenalised against the resonance)
    which = ("a line" if line - math.log(counts.size) > cat[best_cat]
             else "a Markov bias" if best_cat else "the noise model alone")
    reading = catalogue[best_cat]
    rng = np.random.default_rng(NARROW_SEED)
    draws = reading[:, None] * rng.gamma(counts[:, None], 1.0, (counts.size, NARROW_DRAWS)) / counts[:, None]
    values = np.column_stack([data, draws])
    cat_all = _loglik(catalogue, counts, values)
    best = np.maximum(cat_all.max(axis=0), cat_all[0] + _line_gain(catalogue[0], counts, values))
    res_all = _loglik(resonant, counts, values)
    stat = res_all.max(axis=0) - best
    f0, q, power = labels[int(np.argmax(res_all[:, 0]))]
    excess = power * _resonance(test, f0, q)
    sigma = math.sqrt(float(np.sum(excess * counts) / np.sum(counts)))
    tail = (1.0 + float(np.sum(stat[1:] >= stat[0]))) / (NARROW_DRAWS + 1.0)
    return NarrowBand(f0, q, sigma, float(stat[0]), order_statistic_quantile(stat[1:], 1.0 - NARROW_ALPHA), tail,
                      which)


def with_narrow_band(ctx: Context, after: Fit, result: DiscrepancyResult) -> DiscrepancyResult:
    """The workflow's result once the narrow-band test has run on the final refit.

    Fired: ``unexplained``, the band first in ``where``, a named markov_bias below its
    claim (its reading is the one the resonance replaces). Always: a note.
    """
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    noise = replace(ctx.noise, markov_sigma_dph=0.0, markov_tau_s=0.0)
    band = narrow_band_test(WhittleTest(noise, bins, ctx.fs_hz), bins.mean(ctx.resid_full(after)))
    if band is None:
        return result
    notes = [*result.notes, f"narrow-band test: best resonance {band.f0_hz:.2g} Hz, Q {band.q:.2g}, statistic "
                            f"{band.statistic:.1f} against {band.limit:.1f} (best catalogue reading: {band.catalogue})"]
    if not band.fires:
        return replace(result, notes=notes)
    found = [replace(f, probability=f.probability * band.whole_account) if f.name == MARKOV else f
             for f in result.found]
    where = f"{band.describe()}; {result.where}" if result.where else band.describe()
    return replace(result, found=found, unexplained=True, where=where, notes=notes)

