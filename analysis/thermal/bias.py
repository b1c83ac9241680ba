"""Bias and scale factor over temperature: per-temperature values and sensitivities.

The bias a gyro shows on a rate table includes the Earth-rate component
along its input axis; a calibration certificate states the gyro's own bias,
so that component is removed (15.041067 deg/h · sin(latitude) for a vertical
input axis). Bias is input-referred: the output-unit intercept divided by the
scale factor at the same temperature, in deg/h.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.rate.scale_factor import ScaleFactorResult

EARTH_RATE_DPH = 15.041067


def earth_rate_vertical_dph(latitude_deg: float) -> float:
    """Earth-rate component along a vertical (up) input axis at ``latitude_deg``."""
    if not -90.0 <= latitude_deg <= 90.0:
        raise ValueError(f"latitude must be within ±90 deg, got {latitude_deg}")
    return EARTH_RATE_DPH * math.sin(math.radians(latitude_deg))


@dataclass(frozen=True)
class BiasPoint:
    """Input-referred gyro bias (Earth rate removed) at one temperature."""

    temp_c: float
    bias_dph: float

    def to_json(self) -> dict:
        return {"temp_c": self.temp_c, "bias_dph": self.bias_dph}


@dataclass(frozen=True)
class SfTemperature:
    """SF over temperature: σ/mean·100 % and slope relative to SF at the reference."""

    instability_pct: float
    sensitivity_ppm_per_c: float
    sf_at_reference: float

    def to_json(self) -> dict:
        return {"instability_pct": self.instability_pct,
                "sensitivity_ppm_per_c": self.sensitivity_ppm_per_c}


def _line(temps: np.ndarray, values: np.ndarray, what: str) -> tuple[float, float]:
    if np.unique(temps).size < 2:
        raise ValueError(f"{what} over temperature needs at least two temperatures, "
                         f"got {sorted(set(temps.tolist()))}")
    slope, intercept = np.polyfit(temps, values, 1)
    return float(slope), float(intercept)


def bias_by_temperature(results: Sequence[ScaleFactorResult], latitude_deg: float | None = None,
                        earth_rate_dph: float | None = None) -> list[BiasPoint]:
    """Bias in deg/h per temperature from the per-temperature line fits.

    Give ``latitude_deg`` (vertical input axis) or ``earth_rate_dph`` (any
    axis) to remove the Earth-rate component; neither leaves it in.
    """
    if latitude_deg is not None and earth_rate_dph is not None:
        raise ValueError("give latitude_deg or earth_rate_dph, not both")
    earth = earth_rate_dph if earth_rate_dph is not None else (
        earth_rate_vertical_dph(latitude_deg) if latitude_deg is not None else 0.0)
    return [BiasPoint(r.temp_c, r.bias / r.sf * 3600.0 - earth) for r in results]


def bias_sensitivity_dph_per_c(points: Sequence[BiasPoint]) -> float:
    """Least-squares slope of bias against temperature."""
    temps = np.array([p.temp_c for p in points], dtype=float)
    return _line(temps, np.array([p.bias_dph for p in points]), "bias")[0]


def sf_temperature(results: Sequence[ScaleFactorResult], reference_temp_c: float) -> SfTemperature:
    """SF instability (σ/mean·100 %, ddof = 1) and sensitivity (ppm/°C).

    The sensitivity is the least-squares slope of SF(T) divided by the line's
    value at the reference temperature, so it does not hinge on the single
    noisy dwell taken there.
    """
    temps = np.array([r.temp_c for r in results], dtype=float)
    sfs = np.array([r.sf for r in results], dtype=float)
    slope, intercept = _line(temps, sfs, "scale factor")
    sf_ref = slope * reference_temp_c + intercept
    return SfTemperature(
        instability_pct=float(sfs.std(ddof=1) / sfs.mean() * 100.0),
        sensitivity_ppm_per_c=slope / sf_ref * 1e6,
        sf_at_reference=sf_ref,
    )
