"""Pulse-counting quantization, found from the lattice of the output itself.

A pulse-counting gyro (dithered RLG, a FOG with a pulse output) outputs whole
pulses: per sample, output/(sf·fs) is an integer number of pulse angles q
(gyro-model.md, effect ``quantization``). Its error is bounded in angle (0 or
one pulse per readout, never accumulating — Golyaev & Kolbas), so on a
spectrum it shows up as beat lines between the rate and the pulse frequency,
which a line search would call periodic interference at a spurious
frequency. The lattice is a far sharper test than any spectrum: continuous
data essentially never repeats a value, quantized data takes a handful of
levels, each a multiple of q.

The pulse is estimated as the greatest common step of the occupied levels
(the smallest gap between distinct levels, refined by least squares over every
sample with a non-zero count), and the lattice is accepted when nearly every
sample sits on it to within the log's own rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Fraction of samples that must lie on the lattice.
MIN_ON_LATTICE = 0.999
#: Distinct levels must be fewer than this fraction of the samples (continuous data repeats
#: nothing). Not tighter: at 5 Hz a procedure's slews and many dwells made 1,292 levels in
#: 18,000 samples of a 0.5" pulse (7 %); the lattice test itself is what rejects continuous data.
MAX_LEVEL_FRACTION = 0.25
#: A sample lies on the lattice when within this fraction of a pulse of a whole count.
LATTICE_TOLERANCE = 1e-3
#: Smallest pulse taken seriously (arcsec): below it the "lattice" is the log's number formatting.
MIN_PULSE_ARCSEC = 1e-3


@dataclass(frozen=True)
class PulseLattice:
    """The output's pulse angle and how well the samples sit on its lattice."""

    pulse_arcsec: float
    on_lattice: float       # fraction of samples within LATTICE_TOLERANCE of a whole count
    levels: int             # distinct output levels occupied


def angle_per_sample_arcsec(gyro: np.ndarray, scale_factor: float, fs_hz: float) -> np.ndarray:
    """output / (sf·fs), in arcsec: for pulse output, a whole number of pulses per sample."""
    return np.asarray(gyro, dtype=float) / (scale_factor * fs_hz) * 3600.0


def detect_pulse(gyro: np.ndarray, scale_factor: float, fs_hz: float) -> PulseLattice | None:
    """The pulse lattice of a log's output, or None when the output is not pulse-counted."""
    angle = angle_per_sample_arcsec(gyro, scale_factor, fs_hz)
    if angle.size < 100 or not np.all(np.isfinite(angle)):
        return None
    scale = float(np.max(np.abs(angle))) or 1.0
    resolution = scale * 1e-9  # what a log written with ~10 significant digits can resolve
    levels = np.unique(np.round(angle / max(resolution, 1e-300)) * max(resolution, 1e-300))
    if levels.size < 2 or levels.size > MAX_LEVEL_FRACTION * angle.size:
        return None
    gaps = np.diff(levels)
    gaps = gaps[gaps > 100 * resolution]
    if gaps.size == 0:
        return None
    pulse = float(np.min(gaps))
    if pulse < MIN_PULSE_ARCSEC:
        return None
    # Least squares over the counted samples, widening the count range in stages: the
    # smallest gap is only good to the rounding above (3e-4 relative for a 0.5" pulse at
    # 5 Hz, whose largest counts are ~300,000), so counts are trusted only up to ~1/(4·error)
    # of it at first; each stage sharpens the pulse for the next.
    for limit in (1e3, 1e5, np.inf):
        counts = np.round(angle / pulse)
        use = (counts != 0) & (np.abs(counts) <= limit)
        if np.count_nonzero(use) >= 10:
            pulse = float(np.dot(counts[use], angle[use]) / np.dot(counts[use], counts[use]))
    counts = np.round(angle / pulse)
    off = np.abs(angle / pulse - counts)
    on_lattice = float(np.mean(off <= LATTICE_TOLERANCE))
    if on_lattice < MIN_ON_LATTICE:
        return None
    return PulseLattice(pulse, on_lattice, int(levels.size))


def line_within_quantization(amplitude_dph: float, freq_hz: float, pulse_arcsec: float,
                             margin: float = 2.0) -> bool:
    """Whether a rate line is small enough to be the quantization's bounded angle error.

    A rate line A·sin(2πft) (deg/h) moves the angle by A/(2πf) arcsec; quantization
    never moves it by more than a pulse, so a line within ``margin`` pulses of
    angle can be explained by it and must not be named as interference.
    """
    return abs(amplitude_dph) / (2.0 * np.pi * freq_hz) <= margin * pulse_arcsec
