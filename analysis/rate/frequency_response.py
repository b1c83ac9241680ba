"""Frequency response (IEEE Std 952 / IEEE Std 1431, "frequency response"): gain, phase, −3 dB.

At each frequency of a sweep the table turns a sinusoid; a least-squares sine at the
known frequency (sin, cos and a constant) is fitted to the gyro output and to the
reference rate (the table's own readback where it gives one, else the commanded
sinusoid). Gain is the ratio of the amplitudes over the nominal scale factor, phase the
difference of the phases; their standard uncertainties come from the fits' covariances
(residual variance, GUM type A) propagated to first order.

The −3 dB bandwidth is the first crossing of −3.01 dB between two measured frequencies.
Two reasonable interpolations (dB linear in f, dB linear in log f) bracket the crossing of
any smooth response there; the estimate is their middle, with a rectangular type B term
of half-width their whole difference, combined with the type A term from the two
gains' uncertainties. The phase at a stated frequency is interpolated the same way (linear
in f) with the two phases' uncertainties.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

COVERAGE_K = 2.0
MINUS_3DB = -10.0 * math.log10(2.0)


@dataclass(frozen=True)
class Sine:
    amplitude: float
    phase_rad: float
    u_amplitude: float
    u_phase_rad: float


def fit_sine(t_s: np.ndarray, values: np.ndarray, freq_hz: float) -> Sine:
    """y = a·sin(ωt) + b·cos(ωt) + c by least squares; amplitude √(a²+b²), phase atan2(b, a)."""
    w = 2.0 * math.pi * freq_hz
    design = np.column_stack([np.sin(w * t_s), np.cos(w * t_s), np.ones_like(t_s)])
    coef, _, rank, _ = np.linalg.lstsq(design, values, rcond=None)
    if rank < 3:
        raise ValueError(f"{t_s.size} samples cannot resolve a sine at {freq_hz:g} Hz")
    residual = values - design @ coef
    dof = max(values.size - 3, 1)
    cov = np.linalg.inv(design.T @ design) * float(residual @ residual) / dof
    a, b = float(coef[0]), float(coef[1])
    amplitude = math.hypot(a, b)
    grad_amp = np.array([a, b]) / amplitude
    grad_phase = np.array([-b, a]) / amplitude**2
    sub = cov[:2, :2]
    return Sine(amplitude, math.atan2(b, a), math.sqrt(float(grad_amp @ sub @ grad_amp)),
                math.sqrt(float(grad_phase @ sub @ grad_phase)))


@dataclass(frozen=True)
class ResponsePoint:
    freq_hz: float
    gain: float
    u_gain: float
    phase_deg: float
    u_phase_deg: float

    @property
    def gain_db(self) -> float:
        return 20.0 * math.log10(self.gain)

    @property
    def u_gain_db(self) -> float:
        return 20.0 / math.log(10.0) * self.u_gain / self.gain


def response_point(t_s: np.ndarray, output: np.ndarray, reference_dps: np.ndarray,
                   freq_hz: float, scale_factor: float) -> ResponsePoint:
    """Gain and phase of ``output`` (gyro units) against ``reference_dps`` at ``freq_hz``."""
    out, ref = fit_sine(t_s, output, freq_hz), fit_sine(t_s, reference_dps, freq_hz)
    gain = out.amplitude / (scale_factor * ref.amplitude)
    u_gain = gain * math.hypot(out.u_amplitude / out.amplitude, ref.u_amplitude / ref.amplitude)
    phase = math.degrees(math.remainder(out.phase_rad - ref.phase_rad, 2.0 * math.pi))
    u_phase = math.degrees(math.hypot(out.u_phase_rad, ref.u_phase_rad))
    return ResponsePoint(freq_hz, gain, u_gain, phase, u_phase)


@dataclass(frozen=True)
class Bandwidth:
    value_hz: float
    u_hz: float
    u_type_a_hz: float
    half_width_b_hz: float     # rectangular interpolation term

    @property
    def expanded_hz(self) -> float:
        return COVERAGE_K * self.u_hz


def bandwidth_3db(points: list[ResponsePoint]) -> Bandwidth | None:
    """The first −3 dB crossing of the measured gains, with its uncertainty (module docstring)."""
    ordered = sorted(points, key=lambda p: p.freq_hz)
    for low, high in zip(ordered, ordered[1:], strict=False):
        if low.gain_db >= MINUS_3DB > high.gain_db:
            return _crossing(low, high)
    return None


def _crossing(low: ResponsePoint, high: ResponsePoint) -> Bandwidth:
    g1, g2 = low.gain_db, high.gain_db
    fraction = (g1 - MINUS_3DB) / (g1 - g2)
    linear = low.freq_hz + fraction * (high.freq_hz - low.freq_hz)
    logarithmic = low.freq_hz * (high.freq_hz / low.freq_hz) ** fraction
    value = 0.5 * (linear + logarithmic)
    half_width = abs(linear - logarithmic)
    # d(fraction)/d(g1) and /d(g2), through the middle of the two interpolations
    span = g1 - g2
    d_g1 = (1.0 / span - (g1 - MINUS_3DB) / span**2)
    d_g2 = (g1 - MINUS_3DB) / span**2
    d_f = 0.5 * ((high.freq_hz - low.freq_hz)
                 + logarithmic * math.log(high.freq_hz / low.freq_hz))
    u_a = abs(d_f) * math.hypot(d_g1 * low.u_gain_db, d_g2 * high.u_gain_db)
    u = math.hypot(u_a, half_width / math.sqrt(3.0))
    return Bandwidth(value, u, u_a, half_width)


def phase_at(points: list[ResponsePoint], freq_hz: float) -> tuple[float, float] | None:
    """(phase_deg, u_deg) at ``freq_hz``: measured there, or linear between its neighbours."""
    ordered = sorted(points, key=lambda p: p.freq_hz)
    for point in ordered:
        if point.freq_hz == freq_hz:
            return point.phase_deg, point.u_phase_deg
    for low, high in zip(ordered, ordered[1:], strict=False):
        if low.freq_hz < freq_hz < high.freq_hz:
            w = (freq_hz - low.freq_hz) / (high.freq_hz - low.freq_hz)
            return ((1 - w) * low.phase_deg + w * high.phase_deg,
                    math.hypot((1 - w) * low.u_phase_deg, w * high.u_phase_deg))
    return None
