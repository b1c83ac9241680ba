"""Allan curve plus noise-term fit of one rate record, at any length, exact.

Every curve is the fully overlapping estimator at every τ — no block
averages, no thinned start points. A record held in memory is analysed in
place (:func:`allan_curve`); a record too long for memory — a 72 h hold at
2 kHz is 5·10⁸ samples — is streamed from its files in bounded memory
(:func:`allan_curve_streamed`, :mod:`gyrocal.analysis.allan.stream`), with the
same result to the bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrocal.analysis.allan.deviation import (
    AllanResult,
    adev_from_blocks,
    log_spaced_m,
    overlapping_adev,
)
from gyrocal.analysis.allan.noise_fit import TERM_NAMES, NoiseFit, fit_noise_terms
from gyrocal.analysis.allan.stream import RateBlocks

POINTS_PER_DECADE = 10
#: Up to this many samples the phase of a streamed record is kept in memory (128 MiB);
#: beyond, in a temporary file. The result is the same to the bit either way.
IN_MEMORY_SAMPLES = 16_000_000


def curve_m(n_samples: int) -> np.ndarray:
    """The report's τ grid: :data:`POINTS_PER_DECADE` log-spaced m per decade up to N/4."""
    decades = np.log10(max(n_samples // 4, 1))
    return log_spaced_m(n_samples, count=max(int(decades * POINTS_PER_DECADE), 10))


def allan_curve(y, rate_hz: float) -> AllanResult:
    """Overlapping ADEV with intervals of an in-memory record (exact at any length)."""
    data = np.asarray(y, dtype=np.float64)
    return overlapping_adev(data, rate_hz, m=curve_m(data.size))


def allan_curve_streamed(blocks: RateBlocks, n_samples: int, rate_hz: float,
                         tmp_dir: str | Path | None = None) -> AllanResult:
    """The same curve for a record streamed block by block (``blocks()`` re-iterable)."""
    return adev_from_blocks(blocks, rate_hz, m=curve_m(n_samples), tmp_dir=tmp_dir,
                            in_memory=n_samples <= IN_MEMORY_SAMPLES)


def fit_curve(curve: AllanResult) -> NoiseFit:
    """Joint noise-term fit weighted by the curve's EDF and noise types."""
    return fit_noise_terms(curve.tau_s, curve.adev, edf=curve.edf, alpha=curve.alpha)


def curve_json(curve: AllanResult, fit: NoiseFit) -> dict:
    """The `analyze allan --json` object: exactly the keys of interfaces.md."""
    if curve.adev_lo is None or curve.adev_hi is None:
        raise ValueError("the report's curve carries its interval; computed without confidence")
    return curve.to_json("dph") | {"fit": fit.to_json()}


def identifiability_json(fit: NoiseFit) -> dict:
    """Which terms this record can tell from zero, and the 95 % upper bound of each (extra keys).

    ``allan.fit`` keeps the fitted number the contract names; a term that is not
    identifiable is reported as such (HTML, console, acceptance), never as 0.
    """
    terms = {name: getattr(fit, name) for name in TERM_NAMES}
    return {"identifiable": {name: term.identifiable for name, term in terms.items()},
            "upper_bound_95": {name: term.upper_bound() for name, term in terms.items()}}


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
