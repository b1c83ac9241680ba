"""Segments of constant conditions and the bins the likelihood is evaluated on.

A segment is a contiguous run of constant conditions (one procedure step: a
soak, a ramp, a rate dwell); the gap metric compares per-segment residual
means with their noise, and the noise model is estimated on the quiet ones.
Run-folder step labels are used when present; otherwise segments are derived
from the table rate and the chamber temperature trend, and long ones are cut
into windows so slow structure inside a long soak is still seen.

Bins (means of a fixed number of consecutive samples) make the generalised
least squares affordable: a few thousand bin means carry everything slower
than a second or two, and a dense noise covariance of that size is cheap to
factor. Faster structure (periodic interference) is judged on the full-rate
spectrum instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Chamber temperature trend (°C/min) below which the chamber counts as steady.
STEADY_C_PER_MIN = 0.05
#: A change of table rate larger than this (deg/s, plus a relative part) starts a new segment.
RATE_CHANGE_DPS = 1e-3
#: Segments longer than this are cut into equal windows (s).
MAX_SEGMENT_S = 600.0
#: Shorter runs (table accelerations, brief transients) are merged into their neighbour (s).
MIN_SEGMENT_S = 5.0
#: A quiet segment must last this long to enter the noise estimate (s) ...
MIN_QUIET_S = 60.0
#: ... and its first seconds after a change are left out (table settling).
QUIET_SETTLE_S = 2.0


@dataclass(frozen=True)
class Bins:
    """Consecutive groups of ``samples_per_bin`` samples (a trailing remainder is left out)."""

    samples_per_bin: int
    n_bins: int
    centre_s: np.ndarray   # bin centre, from the record start
    width_s: float

    @property
    def n_samples(self) -> int:
        return self.n_bins * self.samples_per_bin

    def mean(self, x: np.ndarray) -> np.ndarray:
        """Bin means of a per-sample array (or of each column of a 2-D array)."""
        x = np.asarray(x, dtype=float)
        body = x[: self.n_samples]
        return body.reshape(self.n_bins, self.samples_per_bin, *x.shape[1:]).mean(axis=1)

    def expand(self, per_bin: np.ndarray) -> np.ndarray:
        """Per-bin values repeated back onto the samples the bins cover."""
        return np.repeat(per_bin, self.samples_per_bin)


def make_bins(t_s: np.ndarray, fs_hz: float, max_bins: int = 3000, min_width_s: float = 1.0) -> Bins:
    """Bins of at least ``min_width_s`` and at most ``max_bins`` of them."""
    n = len(t_s)
    per_bin = max(1, int(round(min_width_s * fs_hz)), math.ceil(n / max_bins))
    n_bins = n // per_bin
    if n_bins < 20:
        raise ValueError(f"{n} samples make only {n_bins} bins of {per_bin}; the log is too short")
    t = np.asarray(t_s[: n_bins * per_bin], dtype=float) - float(t_s[0])
    centre = t.reshape(n_bins, per_bin).mean(axis=1)
    return Bins(per_bin, n_bins, centre, per_bin / fs_hz)


@dataclass(frozen=True)
class Segments:
    """Per-sample segment index, the segments as slices, and which are quiet."""

    index: np.ndarray            # per sample
    slices: tuple[slice, ...]
    names: tuple[str, ...]
    quiet: tuple[bool, ...]

    def __len__(self) -> int:
        return len(self.slices)

    def quiet_slices(self, fs_hz: float) -> list[slice]:
        """Quiet segments without their settling start (for the noise estimate)."""
        skip = int(round(QUIET_SETTLE_S * fs_hz))
        return [slice(s.start + skip, s.stop) for s, q in zip(self.slices, self.quiet, strict=True)
                if q and s.stop - s.start > skip]

    def bin_index(self, bins: Bins) -> np.ndarray:
        """Segment of each bin (the segment of its middle sample)."""
        middle = np.arange(bins.n_bins) * bins.samples_per_bin + bins.samples_per_bin // 2
        return self.index[middle]


def temperature_trend_c_per_min(t_s: np.ndarray, temp_c: np.ndarray, window_s: float = 30.0) -> np.ndarray:
    """Centred difference over ``window_s``: a chamber's control noise must not look like a ramp."""
    n = len(t_s)
    fs = 1.0 / float(np.median(np.diff(t_s)))
    half = max(1, int(round(0.5 * window_s * fs)))
    hi = np.minimum(np.arange(n) + half, n - 1)
    lo = np.maximum(np.arange(n) - half, 0)
    dt = t_s[hi] - t_s[lo]
    return np.where(dt > 0, (temp_c[hi] - temp_c[lo]) / np.where(dt > 0, dt, 1.0) * 60.0, 0.0)


def _runs(codes: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of runs of equal values."""
    change = np.flatnonzero(codes[1:] != codes[:-1]) + 1
    edges = np.concatenate(([0], change, [len(codes)]))
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _merge_short_runs(runs: list[tuple[int, int]], rate_run: np.ndarray, fs: float
                      ) -> list[list[int]]:
    """Absorb only what cannot spoil a segment: flicker of the temperature-trend detector.

    A short run at the *same* table rate as the segment before it (the trend
    detector flickering across its threshold) joins that segment. A short run
    at another rate is a table slew: merged into a constant-rate segment it
    would make the whole segment "table moving" and lose it from the noise
    estimate (a 1 h static followed by a 10-sample slew used to count as 0
    quiet seconds), so consecutive short slew runs become one segment of
    their own, never quiet.
    """
    merged: list[list[int]] = []
    slewing = False
    for a, b in runs:
        short = (b - a) / fs < MIN_SEGMENT_S
        if short and merged and not slewing and rate_run[a] == rate_run[merged[-1][0]]:
            merged[-1][1] = b                      # trend flicker at the same table rate
        elif short and merged and slewing:
            merged[-1][1] = b                      # the slew goes on
        else:
            merged.append([a, b])
            slewing = short and (not merged[:-1] or rate_run[a] != rate_run[merged[-2][0]])
    return merged


def derive_segments(t_s: np.ndarray, table_rate_dps: np.ndarray, chamber_temp_c: np.ndarray,
                    labels: np.ndarray | None = None) -> Segments:
    """Segments from step labels (if any), table-rate changes and the chamber trend."""
    n = len(t_s)
    fs = 1.0 / float(np.median(np.diff(t_s)))
    trend = temperature_trend_c_per_min(t_s, chamber_temp_c)
    regime = np.where(trend > STEADY_C_PER_MIN, 1, np.where(trend < -STEADY_C_PER_MIN, -1, 0))
    rate = np.asarray(table_rate_dps, dtype=float)
    jump = np.abs(np.diff(rate)) > RATE_CHANGE_DPS + 1e-6 * np.abs(rate[1:])
    rate_run = np.concatenate(([0], np.cumsum(jump)))
    code = rate_run * 3 + (regime + 1)
    if labels is not None:
        # only where the label changes matters (segments are runs): number the label's runs
        # instead of sorting 10⁷ strings (np.unique took 14 s on an overnight run)
        label_run = np.concatenate(([0], np.cumsum(labels[1:] != labels[:-1])))
        code = code * (int(label_run[-1]) + 1) + label_run
    runs = _runs(code)
    merged = _merge_short_runs(runs, rate_run, fs)
    slices: list[slice] = []
    names: list[str] = []
    quiet: list[bool] = []
    for a, b in merged:
        length_s = (b - a) / fs
        pieces = max(1, math.ceil(length_s / MAX_SEGMENT_S))
        edges = np.linspace(a, b, pieces + 1).round().astype(int)
        window = slice(a, b)
        steady = bool(np.all(regime[window] == 0))
        constant_rate = bool(np.ptp(rate[window]) <= RATE_CHANGE_DPS + 1e-6 * np.max(np.abs(rate[window])))
        what = ("soak" if steady else "ramp") + (
            f", table {float(np.median(rate[window])):+g} deg/s" if constant_rate else ", table moving")
        if labels is not None:
            what = f"{labels[a]}: {what}"
        for p, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
            slices.append(slice(int(lo), int(hi)))
            names.append(what if pieces == 1 else f"{what} ({p + 1}/{pieces})")
            quiet.append(steady and constant_rate and (hi - lo) / fs >= MIN_QUIET_S)
    index = np.empty(n, dtype=np.int64)
    for k, s in enumerate(slices):
        index[s] = k
    return Segments(index, tuple(slices), tuple(names), tuple(quiet))
