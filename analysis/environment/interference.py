"""Table-induced interference: a static with the table's drive powered against one with it off.

The vendor notes (seeds/003, on FOG testing on a turntable) found that a
powered turntable holding still raised the gyro's drift 5–10× and put
lines at 12.48, 24.96 and 37.44 Hz into its output, which vanished with the
drive off. This module compares the two records of such a test:

* drift: the standard deviation of the τ-second means of each record (the
  usual "zero drift" figure, τ = 1 s unless asked), and their ratio;
* lines: peaks of the powered record's Welch spectrum (Hann window, at
  least 8 segments of ≤ 0.05 Hz bins where the record allows) that stand
  above the noise floor (the spectrum's running median, turned into a mean)
  by more than noise would in one bin out of 10⁶ (the χ² quantile for the
  segments averaged, counted as ν = number of segments: conservative for
  50 % overlap); each is
  refined to the frequency that maximises the record's Fourier amplitude
  there, and its amplitude (0-to-peak, deg/h) is that of the sinusoid at
  that frequency fitted by least squares — in both records, so a line
  present with the drive off as well is said to be so; lines whose
  frequencies are whole multiples of the lowest are named as its harmonics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, signal, stats

#: chance that noise alone passes for a line, per spectral bin
FALSE_LINE_PROBABILITY = 1e-6
#: at most this many lines are reported, strongest first
MAX_LINES = 12


@dataclass(frozen=True)
class SpectralLine:
    frequency_hz: float
    amplitude_dph: float           # 0-to-peak in the powered record
    amplitude_off_dph: float       # the same frequency in the drive-off record
    harmonic: int | None           # n when f ≈ n·f_lowest, else None


@dataclass(frozen=True)
class InterferenceResult:
    drift_tau_s: float
    drift_powered_dph: float
    drift_off_dph: float
    lines: tuple[SpectralLine, ...]

    @property
    def drift_ratio(self) -> float:
        return self.drift_powered_dph / self.drift_off_dph if self.drift_off_dph > 0 else float("inf")

    def to_json(self) -> dict:
        return {"drift_tau_s": self.drift_tau_s, "drift_powered_dph": self.drift_powered_dph,
                "drift_off_dph": self.drift_off_dph, "drift_ratio": self.drift_ratio,
                "lines": [line.__dict__ for line in self.lines]}


def drift_dph(rate_dph: np.ndarray, rate_hz: float, tau_s: float) -> float:
    """Standard deviation of the record's consecutive τ-second means."""
    m = int(round(tau_s * rate_hz))
    n_means = rate_dph.size // m if m >= 1 else 0
    if n_means < 3:
        raise ValueError(f"a drift over {tau_s:g} s needs at least 3 such intervals; the record "
                         f"holds {rate_dph.size / rate_hz:.4g} s")
    return float(rate_dph[: n_means * m].reshape(n_means, m).mean(axis=1).std(ddof=1))


def sine_amplitude(y: np.ndarray, rate_hz: float, frequency_hz: float) -> float:
    """0-to-peak amplitude of the least-squares sinusoid (with offset) at ``frequency_hz``."""
    t = np.arange(y.size) / rate_hz
    design = np.column_stack([np.cos(2 * np.pi * frequency_hz * t),
                              np.sin(2 * np.pi * frequency_hz * t), np.ones(y.size)])
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    return float(np.hypot(coef[0], coef[1]))


def _refine(y: np.ndarray, rate_hz: float, spectrum: np.ndarray, spectrum_hz: np.ndarray,
            f0: float, half_width_hz: float) -> float:
    """The frequency of the largest Fourier amplitude within ±half_width of ``f0``.

    The amplitude against frequency is a sinc whose main lobe is 1/T wide,
    far narrower than a Welch bin, so the 4×-padded FFT of the whole record
    finds the lobe first and a bounded search then centres it.
    """
    near = np.flatnonzero(np.abs(spectrum_hz - f0) <= half_width_hz)
    best = float(spectrum_hz[near[np.argmax(spectrum[near])]])
    step = spectrum_hz[1] - spectrum_hz[0]
    result = optimize.minimize_scalar(lambda f: -sine_amplitude(y, rate_hz, f),
                                      bounds=(best - step, best + step), method="bounded",
                                      options={"xatol": 1e-6})
    return float(result.x)


def find_lines(powered: np.ndarray, off: np.ndarray, rate_hz: float) -> list[SpectralLine]:
    """Lines of the powered record (see the module docstring), in rising frequency."""
    fine = 2 ** int(np.ceil(np.log2(rate_hz / 0.05)))                 # ≤ 0.05 Hz bins
    nperseg = int(min(fine, 2 ** int(np.floor(np.log2(max(powered.size // 8, 16))))))
    freq, psd = signal.welch(powered - powered.mean(), fs=rate_hz, window="hann", nperseg=nperseg)
    dof = max(2, 2 * (powered.size // nperseg) - 1)      # segments averaged at 50 % overlap
    median_to_mean = stats.chi2.median(dof) / dof
    floor = ndimage.median_filter(psd, size=101, mode="nearest") / median_to_mean
    factor = stats.chi2.ppf(1.0 - FALSE_LINE_PROBABILITY, dof) / dof
    above = (psd > factor * floor) & (freq > 2 * rate_hz / nperseg)
    peaks, _ = signal.find_peaks(np.where(above, psd, 0.0))
    peaks = sorted(peaks, key=lambda i: -psd[i])[:MAX_LINES]
    bin_hz = freq[1] - freq[0]
    centred = powered - powered.mean()
    n_fft = 4 * centred.size
    spectrum = np.abs(np.fft.rfft(centred, n=n_fft))
    spectrum_hz = np.fft.rfftfreq(n_fft, 1.0 / rate_hz)
    found = sorted(_refine(powered, rate_hz, spectrum, spectrum_hz, float(freq[i]), bin_hz)
                   for i in peaks)
    lines = []
    lowest = found[0] if found else None
    for f in found:
        n = f / lowest if lowest else 0.0
        harmonic = int(round(n)) if lowest and abs(n - round(n)) < 0.01 else None
        lines.append(SpectralLine(f, sine_amplitude(powered, rate_hz, f),
                                  sine_amplitude(off, rate_hz, f), harmonic))
    return lines


def compare(powered_dph: np.ndarray, off_dph: np.ndarray, rate_hz: float,
            drift_tau_s: float = 1.0) -> InterferenceResult:
    """The drive-powered record against the drive-off one (same sample rate)."""
    powered = np.asarray(powered_dph, dtype=float)
    off = np.asarray(off_dph, dtype=float)
    return InterferenceResult(drift_tau_s, drift_dph(powered, rate_hz, drift_tau_s),
                              drift_dph(off, rate_hz, drift_tau_s),
                              tuple(find_lines(powered, off, rate_hz)))
