"""Where a drifting spectral line might be: the best ridges through short-time spectra of the residual.

The first stage of line_drift.py. The record is cut into segments (K equal
pieces, and the temperature's plateaus, where a line that follows
temperature holds still for a whole soak); each segment's periodogram is
divided by the noise PSD and by its median over the band (as periodic.py
does, so each Fourier bin of noise is Exp(1)) and put on one frequency grid,
and the segments are summed along frequency tracks
f_k = f_ref + slope·(x_k − x̄), x_k the segment's mean temperature or time
("stack-slide", the semi-coherent search of continuous-wave line searches).
A line that stays within a bin for a segment puts its energy in one bin per
segment, so the track through it collects the whole line although no bin of
the whole-record spectrum stands out. A segment's value on a track is the
largest of three neighbouring bins (slopes step by two bins at the extreme
segment); drifts wider than the reach (``MAX_SHIFT_BINS`` for 16 segments or
more, further for fewer) are searched on spectra max-pooled by 2, 4 and 8 bins.

Only the location is taken from here, never a verdict: a 10σ line spread over
16 segments collects about 25 Exp(1) units against noise ridges of about 30
(measured on the five-temperature profile: the ridge alone needed 20σ), so the
``CANDIDATES`` best distinct ridges per covariate go to the coherent test in
line_drift.py, whose union bound does not depend on how they were chosen.
Ridges are ranked by a standardised sum weighted by each segment's expected
share of the line (its length, less what the line smears inside it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.discrepancy.noise_model import NoiseModel

#: Segment counts tried: fewer segments keep more of a slow drift's energy in one bin, more
#: segments keep a fast one (within a segment a line moves slope·(dx/dt)·L² bins).
SEGMENT_COUNTS = (16, 32)
#: Largest shift of a track over the record in (pooled) bins at one pooling level.
MAX_SHIFT_BINS = 96
#: ... for this many segments or more; a segmentation of fewer, K, reaches MAX_SHIFT_BINS·16/K.
REFERENCE_SEGMENTS = 16
#: Pooling levels: 1, 2, 4, 8 bins (shifts up to 8 times the reach).
POOL_LEVELS = 4
#: Distinct tracks per covariate handed to the coherent follow-up: a 10σ line's ridge is not
#: always the best one (about 25 against noise ridges of 30), but it is among the best few.
CANDIDATES = 8
#: Fewer band bins per segment than this: the segment count is not tried.
_MIN_BAND_BINS = 64
#: A plateau: the temperature within this of its start (degC) for at least this long (s).
PLATEAU_C = 0.5
PLATEAU_MIN_S = 120.0
#: A covariate spread (largest |x_k − x̄| over the segments) at or below this is not searched.
MIN_SPREAD = {"temperature": 1.0, "time": 0.0}


@dataclass(frozen=True)
class RidgeTrack:
    """The best track of one covariate: its frequency at x̄, its slope and their resolutions."""

    covariate: str               # "temperature" or "time"
    freq_hz: float               # at the record's mean covariate
    slope_hz_per_unit: float     # Hz per degC, or Hz per second
    freq_resolution_hz: float    # half-width of the track's frequency uncertainty
    slope_resolution: float      # half-width of the slope's uncertainty (Hz per unit)
    statistic: float             # the track's weighted sum, standardised (a z-score under noise)
    n_segments: int
    level: float                 # median normalisation of the segments' ratio (1 = the noise model)


def best_ridges(resid_dph: np.ndarray, fs_hz: float, noise: NoiseModel, f_lo_hz: float,
                covariates: dict[str, np.ndarray], temp_c: np.ndarray | None = None) -> list[RidgeTrack]:
    """The ``CANDIDATES`` best distinct tracks per covariate over every segmentation and pooling.

    The segmentations are K equal pieces for each K of ``SEGMENT_COUNTS`` and, when
    ``temp_c`` has them, its plateaus (``plateaus``), where a line that follows
    temperature holds still for a whole soak. Ranked by the standardised sum; a track
    within its frequency resolution of a better one (the same ridge seen with another
    segmentation) is dropped, one with another slope kept.
    """
    r = np.asarray(resid_dph, dtype=float)
    cuts = [_equal(r.size, k) for k in SEGMENT_COUNTS]
    if temp_c is not None:
        cuts.append(plateaus(np.asarray(temp_c, dtype=float), fs_hz))
    found: dict[str, list[RidgeTrack]] = {}
    for edges in cuts:
        spectra = _segment_spectra(r, fs_hz, noise, f_lo_hz, edges) if len(edges) >= 3 else None
        if spectra is None:
            continue
        ratio, f_band, level = spectra
        for name, values in covariates.items():
            x = np.asarray(values, dtype=float)
            means = np.array([x[a:b].mean() for a, b in edges])
            dx = means - float(np.mean(x))      # about the record's mean, as line_drift's phase is
            if float(np.max(np.abs(dx))) > MIN_SPREAD.get(name, 0.0):
                within = np.array([np.ptp(x[a:b]) for a, b in edges])
                found.setdefault(name, []).extend(_tracks(ratio, f_band, dx, within, name, level,
                                                           np.array([b - a for a, b in edges], float)))
    return [track for tracks in found.values() for track in _distinct(tracks)]


def _equal(n: int, k: int) -> list[tuple[int, int]]:
    length = n // k
    return [(i * length, (i + 1) * length) for i in range(k)]


def plateaus(temp_c: np.ndarray, fs_hz: float) -> list[tuple[int, int]]:
    """(start, stop) of the stretches where the temperature holds within ``PLATEAU_C`` of its
    start for at least ``PLATEAU_MIN_S``; longer ones are cut into pieces of at most an
    eighth of the record (a drift in time must not smear inside one)."""
    n = temp_c.size
    longest = max(n // 8, 1)
    shortest = int(PLATEAU_MIN_S * fs_hz)
    edges: list[tuple[int, int]] = []
    start = 0
    step = max(1, int(fs_hz))                      # scanned once a second
    for i in range(step, n + step, step):
        end = min(i, n)
        if end < n and abs(temp_c[end] - temp_c[start]) <= PLATEAU_C:
            continue
        if end - start >= shortest:
            pieces = int(math.ceil((end - start) / longest))
            bounds = np.linspace(start, end, pieces + 1).astype(int)
            edges.extend(zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True))
        start = end
    return edges


def _distinct(tracks: list[RidgeTrack]) -> list[RidgeTrack]:
    kept: list[RidgeTrack] = []
    for track in sorted(tracks, key=lambda tr: -tr.statistic):
        if all(abs(track.freq_hz - other.freq_hz) > track.freq_resolution_hz + other.freq_resolution_hz
               or abs(track.slope_hz_per_unit - other.slope_hz_per_unit)
               > track.slope_resolution + other.slope_resolution for other in kept):
            kept.append(track)
        if len(kept) == CANDIDATES:
            break
    return kept


def _segment_spectra(r: np.ndarray, fs_hz: float, noise: NoiseModel, f_lo_hz: float,
                     edges: list[tuple[int, int]]):
    """Each segment's periodogram over the noise PSD on one frequency grid: (K × M, f, level).

    The grid's step is the shortest segment's resolution; a longer segment's finer
    bins are max-pooled into it, and each row is standardised by its median and
    spread (a max of q Exp(1) for q pooled bins), so segments of every length rank alike.
    """
    shortest = min(b - a for a, b in edges)
    f = np.fft.rfftfreq(shortest, 1.0 / fs_hz)
    band = (f >= max(f_lo_hz, 2.0 * fs_hz / shortest)) & (f < 0.5 * fs_hz * 0.999)
    if np.count_nonzero(band) < _MIN_BAND_BINS:
        return None
    grid = f[band]
    df = float(grid[1] - grid[0])
    rows, levels = [], []
    for a, b in edges:
        seg = r[a:b] - float(np.mean(r[a:b]))
        f_seg = np.fft.rfftfreq(seg.size, 1.0 / fs_hz)
        keep = (f_seg >= grid[0] - 0.5 * df) & (f_seg < grid[-1] + 0.5 * df)
        ratio = np.abs(np.fft.rfft(seg)[keep]) ** 2 / (seg.size * fs_hz)
        ratio = ratio / noise.psd_two_sided(f_seg[keep], fs_hz)
        levels.append(float(np.median(ratio)) / math.log(2.0))
        cell = np.clip(np.rint((f_seg[keep] - grid[0]) / df).astype(int), 0, grid.size - 1)
        row = np.zeros(grid.size)
        np.maximum.at(row, cell, ratio / levels[-1])
        rows.append(row)
    return np.vstack(rows), grid, float(np.median(levels))


def _tracks(ratio: np.ndarray, f_band: np.ndarray, dx: np.ndarray, within: np.ndarray, covariate: str,
            level: float, length: np.ndarray) -> list[RidgeTrack]:
    """The ``CANDIDATES`` best tracks at each pooling level, far enough apart in frequency.

    ``within`` is each segment's covariate range: on a track of shift m a line moves
    |m|·within/spread bins inside the segment, so the segment is weighted by the
    share of its power one bin keeps, 1/max(1, that); the sum is standardised by
    the mean and spread of a segment's maximum of q Exp(1) under noise.
    """
    k = ratio.shape[0]
    spread = float(np.max(np.abs(dx)))
    u, smear = dx / spread, within / spread
    df = float(f_band[1] - f_band[0])
    out: list[RidgeTrack] = []
    # fewer segments (the plateaus) cost less per slope and reach further: a line moving 0.1 %/°C
    # at 7 Hz crosses 220 bins of a 15-minute soak's spectrum over 35 °C, where a pooled
    # spectrum dilutes it below the noise ridges)
    reach = max(MAX_SHIFT_BINS, 2 * int(MAX_SHIFT_BINS * REFERENCE_SEGMENTS / (2 * k)))
    for level_index in range(POOL_LEVELS):
        pool = 2 ** level_index
        widened = _three_bin_max(_pool(ratio, pool))
        if widened.shape[1] < 2 * reach:
            break
        widened = _standardised(widened).astype(np.float32)   # half the memory traffic of the sums
        lowest = 0 if level_index == 0 else reach // 2 + 2
        shifts = np.arange(lowest, reach + 1, 2)
        shifts = np.concatenate([shifts, -shifts[shifts > 0]])
        best_sum = np.full(widened.shape[1], -np.inf, dtype=np.float32)
        best_shift = np.zeros(widened.shape[1], dtype=int)
        for index, m in enumerate(shifts):      # a running maximum: no (shifts × bins) array
            total = _track_sum(widened, np.rint(m * u).astype(int), _weights(m * smear, length))
            better = total > best_sum
            best_sum[better] = total[better]
            best_shift[better] = index
        for j in _peaks(best_sum, reach):
            out.append(RidgeTrack(covariate, float(f_band[0] + (j * pool + 0.5 * (pool - 1)) * df),
                                  float(shifts[best_shift[j]]) * pool * df / spread, (1.5 * pool + 0.5) * df,
                                  2.0 * pool * df / spread, float(best_sum[j]), k, level))
    return out


def _weights(smear_bins: np.ndarray, length: np.ndarray) -> np.ndarray:
    """A segment's expected share of a line's power in one bin: its length, less its smear."""
    w = length / np.maximum(1.0, np.abs(smear_bins))
    return w / math.sqrt(float(np.sum(w * w)))


def _standardised(x: np.ndarray) -> np.ndarray:
    """Each row less its median, over its spread (1.4826 MAD): noise bins rank alike in every segment."""
    sample = x[:, :: max(1, x.shape[1] // 4096)]        # a few thousand bins fix a median well
    med = np.median(sample, axis=1, keepdims=True)
    mad = 1.4826 * np.median(np.abs(sample - med), axis=1, keepdims=True)
    return (x - med) / np.where(mad > 0, mad, 1.0)


def _peaks(values: np.ndarray, apart: int) -> list[int]:
    """Indices of the ``CANDIDATES`` largest values, each at least ``apart`` from a larger one."""
    picked: list[int] = []
    for j in np.argsort(values)[::-1][: 50 * CANDIDATES]:
        if all(abs(int(j) - p) >= apart for p in picked):
            picked.append(int(j))
            if len(picked) == CANDIDATES:
                break
    return picked


def _pool(ratio: np.ndarray, pool: int) -> np.ndarray:
    if pool == 1:
        return ratio
    usable = (ratio.shape[1] // pool) * pool
    return ratio[:, :usable].reshape(ratio.shape[0], -1, pool).max(axis=2)


def _three_bin_max(x: np.ndarray) -> np.ndarray:
    out = x.copy()
    out[:, 1:] = np.maximum(out[:, 1:], x[:, :-1])
    out[:, :-1] = np.maximum(out[:, :-1], x[:, 1:])
    return out


def _track_sum(x: np.ndarray, shift: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Σ_k w_k·x[k, j + shift_k] for every j (beyond the band counts 0)."""
    n = x.shape[1]
    total = np.zeros(n, dtype=x.dtype)
    weight = weight.astype(x.dtype)
    for k, s in enumerate(shift):
        if s >= 0:
            total[: n - s] += weight[k] * x[k, s:]
        else:
            total[-s:] += weight[k] * x[k, : n + s]
    return total
