"""Overlapping Allan deviation of gyro rate data, fast and exact, with confidence intervals.

An overnight static run at 100–1000 Hz is 10⁷ samples or more, and the
Allan curve is what QA signs the noise figures off from. The textbook
estimator is O(N) per τ from one cumulative sum (the phase), so the cost is
in memory traffic, not arithmetic: this module makes one phase array (the
only large allocation, 1× the input) and evaluates each τ in cache-sized
chunks, never materialising the full second-difference array. The arithmetic
is the same, operation for operation, as ``allantools.oadev(data_type="freq")``
(mean removed before the cumulative sum, then x[i+2m] − 2x[i+m] + x[i]) so
both agree to rounding of the final sum.

Precision note: like every phase-based implementation, the second difference
of a cumulative sum loses about ε·max|x| absolutely. Removing the mean first
keeps that small for noise around a bias; a record dominated by a large rate
random walk (max|x| ~ N^1.5·σ) loses relative precision ~ ε·N^1.5 at τ0.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrocal.analysis.allan.edf import ONE_SIGMA_CONFIDENCE, chi2_interval, edf_greenhall
from gyrocal.analysis.allan.noise_id import alpha_per_m_from_decimated, identify_alpha_per_m
from gyrocal.analysis.allan.stream import (
    BLOCK,
    WINDOW,
    FilePhase,
    MemoryPhase,
    RateBlocks,
    record_stats,
    second_difference_totals,
    write_phase,
)

_CHUNK = 1 << 16  # elements per pass: 3 input slices + 1 buffer stay inside L2 cache


#: How every curve here is computed: both paths (in memory, streamed) give the same numbers.
METHOD = "fully overlapping, exact"


@dataclass(frozen=True)
class AllanResult:
    """Overlapping ADEV per averaging time, in the units of the input rate.

    The one Allan curve type: :func:`overlapping_adev`, :func:`adev_from_blocks` and the
    report's curves (:mod:`gyrocal.analysis.allan.summary`) all return it.

    ``n_terms`` is the number of second differences averaged at each τ;
    ``alpha`` the noise type used for the EDF (see :mod:`noise_id`);
    ``adev_lo``/``adev_hi`` the chi-squared interval at ``confidence``
    (None when confidence intervals were not requested).
    """

    tau_s: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray
    m: np.ndarray
    rate_hz: float
    n_samples: int
    alpha: np.ndarray | None = None
    edf: np.ndarray | None = None
    adev_lo: np.ndarray | None = None
    adev_hi: np.ndarray | None = None
    confidence: float | None = None

    @property
    def method(self) -> str:
        """The estimator, as the report and ``analyze allan`` name it."""
        return METHOD

    def to_json(self, units_suffix: str = "dph") -> dict:
        """The `analyze allan --json` curve keys; the suffix names the input units."""
        out = {
            "tau_s": self.tau_s.tolist(),
            f"adev_{units_suffix}": self.adev.tolist(),
        }
        if self.adev_lo is not None and self.adev_hi is not None:
            out[f"adev_lo_{units_suffix}"] = self.adev_lo.tolist()
            out[f"adev_hi_{units_suffix}"] = self.adev_hi.tolist()
        return out


def log_spaced_m(n_samples: int, count: int = 100, stop_ratio: int = 4) -> np.ndarray:
    """About ``count`` log-spaced averaging factors from 1 to n_samples/stop_ratio.

    The stop ratio (4, as Stable32 uses for OADEV) keeps at least ~2 m
    independent terms at the longest τ; below that the estimate is noise.
    """
    if n_samples < 2 * stop_ratio:
        raise ValueError(f"{n_samples} samples are too few for an Allan curve")
    max_m = max(1, n_samples // stop_ratio)
    raw = np.logspace(0.0, np.log10(max_m), int(count))
    return np.unique(np.round(raw).astype(np.int64))


def _phase_from_rate(y: np.ndarray, rate_hz: float) -> np.ndarray:
    """x[0] = 0, x[k] = τ0·Σ_{i<k}(y_i − ȳ): one allocation of N+1 floats."""
    phase = np.empty(y.size + 1, dtype=np.float64)
    phase[0] = 0.0
    body = phase[1:]
    np.subtract(y, y.mean(), out=body)
    np.cumsum(body, out=body)
    body *= 1.0 / float(rate_hz)
    return phase


def _sum_second_differences_squared(phase: np.ndarray, m: int, buffer: np.ndarray) -> float:
    """Σ (x[i+2m] − 2x[i+m] + x[i])² over all i, chunk by chunk."""
    n_terms = phase.size - 2 * m
    total = 0.0
    for start in range(0, n_terms, _CHUNK):
        stop = min(start + _CHUNK, n_terms)
        view = buffer[: stop - start]
        np.multiply(phase[start + m : stop + m], 2.0, out=view)
        np.subtract(phase[start + 2 * m : stop + 2 * m], view, out=view)
        np.add(view, phase[start:stop], out=view)
        total += float(np.dot(view, view))
    return total


def _validated_rate(y, rate_hz: float) -> np.ndarray:
    data = np.asarray(y, dtype=np.float64)
    if data.ndim != 1:
        raise ValueError(f"rate data must be one-dimensional, got shape {data.shape}")
    if not rate_hz > 0:
        raise ValueError(f"sample rate must be positive, got {rate_hz} Hz")
    if data.size < 8:
        raise ValueError(f"{data.size} samples are too few for an Allan curve")
    if not np.isfinite(data).all():
        bad = int(np.flatnonzero(~np.isfinite(data))[0])
        raise ValueError(f"rate data has a non-finite value at sample {bad}: {data[bad]}")
    return data


def _resolve_m(n_samples: int, rate_hz: float, m, taus_s) -> np.ndarray:
    if m is not None and taus_s is not None:
        raise ValueError("give either m or taus_s, not both")
    if taus_s is not None:
        m = np.round(np.asarray(taus_s, dtype=float) * rate_hz)
    if m is None:
        return log_spaced_m(n_samples)
    values = np.unique(np.asarray(m, dtype=np.int64))
    too_big = values[2 * values > n_samples]
    if values.size == 0 or values[0] < 1 or too_big.size:
        raise ValueError(
            f"averaging factors must be 1…{n_samples // 2} for {n_samples} samples, "
            f"got {values.min() if values.size else 'none'}…{values.max() if values.size else ''}")
    return values


def overlapping_adev(y, rate_hz: float, m=None, taus_s=None,
                     confidence: float | None = ONE_SIGMA_CONFIDENCE,
                     compiled: bool = True) -> AllanResult:
    """Overlapping Allan deviation of rate samples ``y`` taken at ``rate_hz``.

    Same definition as ``allantools.oadev(y, rate_hz, data_type="freq")``.
    ``m`` (averaging factors) or ``taus_s`` choose the τ grid, default
    :func:`log_spaced_m`. With ``confidence`` (default 68.3 %), each τ gets
    a noise type, Greenhall's EDF and a chi-squared interval; pass None to
    skip them. ``compiled=False`` forces the independent pure-numpy path (the
    oracle for the compiled, tiled kernels of :mod:`gyrocal.analysis.allan.kernel`).
    Exact at any length that fits in memory; for longer records stream them
    with :func:`adev_from_blocks`.
    """
    data = _validated_rate(y, rate_hz)
    if compiled:
        return adev_from_blocks(lambda: (data,), rate_hz, m=m, taus_s=taus_s,
                                confidence=confidence, in_memory=True)
    m_values = _resolve_m(data.size, rate_hz, m, taus_s)
    phase = _phase_from_rate(data, rate_hz)
    buffer = np.empty(min(_CHUNK, phase.size), dtype=np.float64)
    totals = np.array([_sum_second_differences_squared(phase, int(mj), buffer)
                       for mj in m_values])
    alpha = identify_alpha_per_m(phase, m_values) if confidence is not None else None
    return _result(totals, m_values, data.size, rate_hz, confidence, alpha)


def adev_from_blocks(blocks: RateBlocks, rate_hz: float, m=None, taus_s=None,
                     confidence: float | None = ONE_SIGMA_CONFIDENCE,
                     in_memory: bool = False, tmp_dir: str | Path | None = None,
                     block: int = BLOCK, window: int = WINDOW) -> AllanResult:
    """Exact overlapping ADEV of a record given as a re-iterable stream of rate blocks.

    ``blocks()`` must yield the record from its start each time it is called
    (it is read twice: for the mean, then for the phase). With
    ``in_memory=False`` the phase goes to a temporary file in ``tmp_dir``
    (default: the system's), so peak memory is a few 64 MiB buffers whatever
    the length; the result is bit-for-bit the in-memory one
    (:mod:`gyrocal.analysis.allan.stream`). ``block`` (a multiple of the
    kernel's tile) and ``window`` set the buffers' sizes; tests make them
    small to exercise the rolling window and the long-τ path on short records.
    """
    if not rate_hz > 0:
        raise ValueError(f"sample rate must be positive, got {rate_hz} Hz")
    stats = record_stats(blocks())
    if stats.n_samples < 8:
        raise ValueError(f"{stats.n_samples} samples are too few for an Allan curve")
    m_values = _resolve_m(stats.n_samples, rate_hz, m, taus_s)
    store = MemoryPhase(stats.n_samples + 1) if in_memory else FilePhase(tmp_dir)
    try:
        decimated = write_phase(blocks(), stats, rate_hz, store,
                                m_values if confidence is not None else None)
        totals = second_difference_totals(store, m_values, block=block,
                                          window=max(block, window))
    finally:
        store.close()
    alpha = alpha_per_m_from_decimated(decimated) if confidence is not None else None
    return _result(totals, m_values, stats.n_samples, rate_hz, confidence, alpha)


def _result(totals: np.ndarray, m_values: np.ndarray, n_samples: int, rate_hz: float,
            confidence: float | None, alpha: np.ndarray | None) -> AllanResult:
    n_terms = n_samples + 1 - 2 * m_values
    adev = np.sqrt(totals / (2.0 * n_terms)) / m_values * rate_hz
    tau_s = m_values / float(rate_hz)
    if confidence is None or alpha is None:
        return AllanResult(tau_s, adev, n_terms, m_values, float(rate_hz), n_samples)
    edf = np.array([edf_greenhall(int(a), 2, int(mj), n_samples + 1)
                    for a, mj in zip(alpha, m_values, strict=True)])
    adev_lo, adev_hi = chi2_interval(adev, edf, confidence)
    return AllanResult(tau_s, adev, n_terms, m_values, float(rate_hz), n_samples,
                       alpha=alpha, edf=edf, adev_lo=adev_lo, adev_hi=adev_hi,
                       confidence=confidence)
