"""Noise generated from a known truth, for the Allan and noise-fit tests.

Kept independent of the simulator in ``models/`` (written in parallel): each
generator is a few lines of numpy whose Allan variance is known in closed form
(IEEE 952 Annex C), so a recovered coefficient can be compared with the truth.
All rates are in deg/h, sample rate ``fs_hz``.
"""

from __future__ import annotations

import numpy as np
import pytest


class NoiseTruth:
    """Generators keyed by the IEEE 952 coefficient they realise."""

    @staticmethod
    def white_rate(rng, n, fs_hz, arw_deg_per_rth):
        """ARW N: white rate noise, per-sample std N·60·√fs (deg/h)."""
        return rng.standard_normal(n) * (arw_deg_per_rth * 60.0 * np.sqrt(fs_hz))

    @staticmethod
    def rate_random_walk(rng, n, fs_hz, rrw_dph_per_rth):
        """RRW K: cumulative sum of white steps of std K·√(τ0 in hours)."""
        return np.cumsum(rng.standard_normal(n)) * (rrw_dph_per_rth * np.sqrt(1.0 / fs_hz / 3600.0))

    @staticmethod
    def quantization(rng, n, fs_hz, q_arcsec):
        """Q: white angle noise (std Q arcsec) differenced; arcsec/s equals deg/h."""
        angle = rng.standard_normal(n + 1) * q_arcsec
        return np.diff(angle) * fs_hz

    @staticmethod
    def markov(rng, n, fs_hz, sigma_dph, tau_s):
        """First-order Gauss–Markov, steady-state std σ, correlation time T (exact AR(1))."""
        from scipy.signal import lfilter

        phi = np.exp(-1.0 / (fs_hz * tau_s))
        drive = rng.standard_normal(n) * (sigma_dph * np.sqrt(1.0 - phi**2))
        first = rng.standard_normal() * sigma_dph
        out, _ = lfilter([1.0], [1.0, -phi], drive, zi=[phi * first])
        return out

    @staticmethod
    def flicker_rate(rng, n, fs_hz, bias_instability_dph):
        """B: flicker rate noise by FFT shaping.

        IEEE 952 writes the flicker PSD two-sided, S(f) = B²/(2π f); the one-sided
        PSD that a white sequence of unit variance (one-sided PSD 2/fs) is shaped
        to is twice that, B²/(π f).
        """
        spectrum = np.fft.rfft(rng.standard_normal(n))
        f = np.fft.rfftfreq(n, d=1.0 / fs_hz)
        gain = np.zeros_like(f)
        gain[1:] = np.sqrt(bias_instability_dph**2 / (np.pi * f[1:]) * fs_hz / 2.0)
        return np.fft.irfft(spectrum * gain, n)


@pytest.fixture
def noise_truth() -> type[NoiseTruth]:
    return NoiseTruth
