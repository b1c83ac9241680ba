"""Allan curve plus noise-term fit of one rate record, sized for an overnight hold.

The exact fully overlapping estimator (:func:`gyrocal.reports.allan.overlapping_adev`)
costs one pass over the record per τ; with its compiled kernel a 3 h hold at
2 kHz (2.2·10⁷ samples, ~100 τ) takes about 3–4 s on a 2-core machine, so it
is used up to :data:`EXACT_LIMIT_SAMPLES` (longer than any overnight hold).
Above that the curve is computed on a
pyramid of block averages: τ = m·τ0 is evaluated on the record averaged in
blocks of d samples (d a power of two, d ≤ m/:data:`MIN_M_PER_BLOCK` = m/4), with
m rounded to a multiple of d. Each Allan difference used is still exact
(an average of d·m' samples is an average of m samples); only the start
points are spaced d ≤ m/4 apart instead of 1, which costs some
EDF, and the confidence interval is computed for the estimator actually
used (Greenhall EDF of the block-averaged series), so it stays honest.
Below the limit the curve is the exact one, equal to allantools.oadev.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.reports.allan import log_spaced_m, overlapping_adev
from gyrocal.reports.noise_fit import TERM_NAMES, NoiseFit, fit_noise_terms

EXACT_LIMIT_SAMPLES = 25_000_000
MIN_M_PER_BLOCK = 4
POINTS_PER_DECADE = 10


@dataclass(frozen=True)
class AllanCurve:
    """ADEV per τ (input units, normally deg/h) with its 68 % interval, EDF and noise type."""

    tau_s: np.ndarray
    adev: np.ndarray
    adev_lo: np.ndarray
    adev_hi: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    n_samples: int
    rate_hz: float
    method: str


def _block_means(y: np.ndarray, block: int) -> np.ndarray:
    usable = (y.size // block) * block
    return y[:usable].reshape(-1, block).mean(axis=1)


def _pyramid_m(n_samples: int) -> dict[int, np.ndarray]:
    """Averaging factors grouped by block size d: {d: m/d values}."""
    decades = np.log10(max(n_samples // 4, 1))
    wanted = log_spaced_m(n_samples, count=max(int(decades * POINTS_PER_DECADE), 10))
    groups: dict[int, set[int]] = {}
    for m in wanted:
        block = 1
        while block * 2 * MIN_M_PER_BLOCK <= m:
            block *= 2
        groups.setdefault(block, set()).add(max(int(round(m / block)), 1))
    return {block: np.array(sorted(ms)) for block, ms in sorted(groups.items())}


def allan_curve(y, rate_hz: float) -> AllanCurve:
    """Overlapping ADEV with intervals; exact below :data:`EXACT_LIMIT_SAMPLES` (module doc)."""
    data = np.asarray(y, dtype=np.float64)
    if data.size <= EXACT_LIMIT_SAMPLES:
        result = overlapping_adev(data, rate_hz)
        return AllanCurve(result.tau_s, result.adev, result.adev_lo, result.adev_hi, result.edf,
                          result.alpha, data.size, float(rate_hz), "overlapping (exact)")
    parts = []
    level, level_block = data, 1
    for block, m_values in _pyramid_m(data.size).items():
        while level_block < block:
            level = _block_means(level, 2)
            level_block *= 2
        m_ok = m_values[2 * m_values <= level.size]
        if m_ok.size == 0:
            continue
        parts.append(overlapping_adev(level, rate_hz / block, m=m_ok))
    tau = np.concatenate([p.tau_s for p in parts])
    order = np.argsort(tau, kind="stable")
    keep = order[np.concatenate([[True], np.diff(tau[order]) > 0])]

    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in parts])[keep]

    return AllanCurve(tau[keep], joined("adev"), joined("adev_lo"), joined("adev_hi"),
                      joined("edf"), joined("alpha"), data.size, float(rate_hz),
                      f"overlapping on block averages (start stride ≤ m/{MIN_M_PER_BLOCK})")


def fit_curve(curve: AllanCurve) -> NoiseFit:
    """Joint noise-term fit weighted by the curve's EDF and noise types."""
    return fit_noise_terms(curve.tau_s, curve.adev, edf=curve.edf, alpha=curve.alpha)


def curve_json(curve: AllanCurve, fit: NoiseFit) -> dict:
    """The `analyze allan --json` object: exactly the keys of interfaces.md."""
    return {
        "tau_s": curve.tau_s.tolist(),
        "adev_dph": curve.adev.tolist(),
        "adev_lo_dph": curve.adev_lo.tolist(),
        "adev_hi_dph": curve.adev_hi.tolist(),
        "fit": fit.to_json(),
    }


def fit_uncertainty_json(fit: NoiseFit) -> dict:
    """Standard error and 68 % interval of each fitted term (extra results.json key)."""
    out = {}
    for name in TERM_NAMES:
        term = getattr(fit, name)
        out[name] = {"stderr": term.stderr, "lo": term.lo, "hi": term.hi}
    if fit.markov is not None:
        for key in ("sigma_dph", "tau_s"):
            term = getattr(fit.markov, key)
            out[f"markov.{key}"] = {"stderr": term.stderr, "lo": term.lo, "hi": term.hi}
    return out
