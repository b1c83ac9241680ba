"""One table-rate dwell reduced to the numbers the scale-factor analysis needs.

Every SF, bias and nonlinearity figure is built from dwell means, so how a
dwell is reduced matters: the settle part after the table reaches rate is
dropped, and the mean can be taken over whole table revolutions so that
anything periodic in table angle (tilt sensing Earth's horizontal rate, table
wobble, the room's magnetic field) averages out instead of leaking into the SF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Dwell:
    """Mean gyro output during one constant-rate dwell at one temperature.

    ``rate_dps`` is the table rate (deg/s, signed), ``output_mean`` and
    ``output_std`` are in the gyro's output units, ``n_samples`` the samples
    averaged (after discarding the settle part).
    """

    temp_c: float
    rate_dps: float
    output_mean: float
    output_std: float = 0.0
    n_samples: int = 1


@dataclass(frozen=True)
class DwellStats:
    """Mean, standard deviation and count of the samples kept from a dwell."""

    mean: float
    std: float
    n_samples: int


def dwell_mean(samples, fs_hz: float, settle_s: float, rate_dps: float = 0.0,
               revolutions: int | str | None = None) -> DwellStats:
    """Mean of a dwell's samples after ``settle_s``, optionally over whole revolutions.

    ``revolutions``: None keeps every sample after settling; an integer keeps
    exactly that many table revolutions (an error if the dwell is shorter);
    "all" keeps as many whole revolutions as fit. Revolutions need a non-zero
    ``rate_dps``.
    """
    data = np.asarray(samples, dtype=float)
    if data.ndim != 1:
        raise ValueError(f"dwell samples must be one-dimensional, got shape {data.shape}")
    if not fs_hz > 0 or settle_s < 0:
        raise ValueError(f"need fs_hz > 0 and settle_s >= 0, got {fs_hz} Hz, {settle_s} s")
    kept = data[int(math.ceil(settle_s * fs_hz)):]
    if revolutions is not None:
        if rate_dps == 0:
            raise ValueError("trimming to whole revolutions needs a non-zero rate_dps")
        samples_per_rev = 360.0 / abs(rate_dps) * fs_hz
        available = int(kept.size // samples_per_rev)
        if revolutions == "all":
            wanted = available
        elif isinstance(revolutions, int) and revolutions > 0:
            wanted = revolutions
        else:
            raise ValueError(f"revolutions must be a positive int, 'all' or None, got {revolutions!r}")
        if wanted < 1 or wanted > available:
            raise ValueError(
                f"dwell at {rate_dps} deg/s has {kept.size / fs_hz:.1f} s after settling: "
                f"{available} whole revolution(s), {wanted} asked")
        kept = kept[: int(round(wanted * samples_per_rev))]
    if kept.size == 0:
        raise ValueError(f"no samples left after a {settle_s} s settle ({data.size} samples)")
    if not np.isfinite(kept).all():
        bad = int(np.flatnonzero(~np.isfinite(kept))[0])
        raise ValueError(f"dwell sample {bad} after settling is not finite: {kept[bad]}")
    std = float(kept.std(ddof=1)) if kept.size > 1 else 0.0
    return DwellStats(float(kept.mean()), std, int(kept.size))


def dwell_from_samples(temp_c: float, rate_dps: float, samples, fs_hz: float, settle_s: float,
                       revolutions: int | str | None = None) -> Dwell:
    """Reduce raw samples to a :class:`Dwell` (see :func:`dwell_mean`)."""
    stats = dwell_mean(samples, fs_hz, settle_s, rate_dps, revolutions)
    return Dwell(temp_c, rate_dps, stats.mean, stats.std, stats.n_samples)


@dataclass(frozen=True)
class SegmentDrift:
    """How far the worst part of a dwell strays from the rest of it, and what noise allows.

    ``deviation`` and ``noise_limit`` are in output units; ``segment`` is the
    0-based index of the worst of ``segments`` equal parts.
    """

    deviation: float
    noise_limit: float
    segment: int
    segments: int

    def to_json(self) -> dict:
        return {"deviation": self.deviation, "noise_limit": self.noise_limit,
                "segment": self.segment, "segments": self.segments}


def segment_drift(samples, segments: int = 10, n_sigma: float = 8.0,
                  min_per_segment: int = 10) -> SegmentDrift | None:
    """Split a dwell into ``segments`` parts; the part whose mean strays farthest from the rest.

    Why: a dwell's mean is only its rate's output if every part of it saw
    that rate. Samples from before the table settled (issue 28: the end of
    the table's ramp logged as a dwell's first samples) or a table that
    wandered during the dwell show as one part far from the others, while
    the mean of the whole would hide them in a biased scale factor. Each
    part is compared with the mean of all the others; ``noise_limit`` is
    ``n_sigma`` standard errors of that difference (white noise, from the
    parts' own scatter). None if the dwell is too short to split.
    """
    data = np.asarray(samples, dtype=float)
    if data.ndim != 1 or segments < 2 or data.size < segments * min_per_segment:
        return None
    parts = np.array_split(data, segments)
    n = np.array([p.size for p in parts], dtype=float)
    sums = np.array([p.sum() for p in parts])
    var = np.array([p.var(ddof=1) for p in parts])
    worst: SegmentDrift | None = None
    for j in range(segments):
        rest_n = n.sum() - n[j]
        rest_mean = (sums.sum() - sums[j]) / rest_n
        rest_var = (np.dot(var, n - 1) - var[j] * (n[j] - 1)) / (rest_n - segments + 1)
        limit = n_sigma * math.sqrt(var[j] / n[j] + rest_var / rest_n)
        drift = SegmentDrift(float(abs(sums[j] / n[j] - rest_mean)), float(limit), j, segments)
        if worst is None or drift.deviation - drift.noise_limit > worst.deviation - worst.noise_limit:
            worst = drift
    return worst
