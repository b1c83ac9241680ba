"""Temperature compensation tables for bias and scale factor, with honest residuals.

The vendor method is a piecewise-linear table: the measured points, with
linear interpolation between them (cheap enough for real-time use). Its
in-sample residual is zero by construction, which says nothing; the residual
reported is leave-one-out — each point predicted from the table without it
(interpolated between its neighbours, or extrapolated from the two nearest at
the ends) — i.e. what the table would leave at a temperature it was not
calibrated at. A least-squares polynomial (degree chosen by the caller) is
given alongside with both its in-sample and leave-one-out residuals.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class CompensationTable:
    """A value-vs-temperature compensation with the residual it leaves.

    ``points`` are (temp_c, value) pairs: the measured points for the
    piecewise table, the fitted values at the measured temperatures for the
    polynomial. ``coefficients`` (highest power first) only for the polynomial.
    """

    kind: str
    points: list[list[float]]
    residual_rms: float
    loo_residual_rms: float
    loo_residual_max: float
    coefficients: list[float] | None = None

    def evaluate(self, temp_c) -> np.ndarray:
        """Compensation value at ``temp_c`` (linear extrapolation beyond the table)."""
        t = np.asarray(temp_c, dtype=float)
        if self.coefficients is not None:
            return np.polyval(self.coefficients, t)
        temps = np.array([p[0] for p in self.points])
        values = np.array([p[1] for p in self.points])
        return interp_extrap(temps, values, t)

    def to_pairs(self) -> list[list[float]]:
        """[[temp_c, value], …] for results.json."""
        return [[float(t), float(v)] for t, v in self.points]


def interp_extrap(temps: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    inside = np.interp(t, temps, values)
    low_slope = (values[1] - values[0]) / (temps[1] - temps[0])
    high_slope = (values[-1] - values[-2]) / (temps[-1] - temps[-2])
    below = values[0] + low_slope * (t - temps[0])
    above = values[-1] + high_slope * (t - temps[-1])
    return np.where(t < temps[0], below, np.where(t > temps[-1], above, inside))


def _sorted_points(temps_c: Sequence[float], values: Sequence[float], minimum: int):
    temps = np.asarray(temps_c, dtype=float)
    vals = np.asarray(values, dtype=float)
    if temps.shape != vals.shape or temps.ndim != 1:
        raise ValueError(f"temperatures and values must be 1-D of equal length, "
                         f"got {temps.shape} and {vals.shape}")
    if not (np.isfinite(temps).all() and np.isfinite(vals).all()):
        raise ValueError("temperatures and values must be finite")
    order = np.argsort(temps)
    temps, vals = temps[order], vals[order]
    if np.any(np.diff(temps) == 0):
        raise ValueError(f"duplicate temperature in {temps.tolist()}: average the points first")
    if temps.size < minimum:
        raise ValueError(f"{temps.size} temperatures given, at least {minimum} needed")
    return temps, vals


def piecewise_linear(temps_c: Sequence[float], values: Sequence[float]) -> CompensationTable:
    """Vendor table: measured points, linear between them; leave-one-out residual."""
    temps, vals = _sorted_points(temps_c, values, minimum=3)
    loo = np.empty(temps.size)
    for i in range(temps.size):
        keep = np.arange(temps.size) != i
        loo[i] = vals[i] - interp_extrap(temps[keep], vals[keep], temps[i : i + 1])[0]
    return CompensationTable(
        kind="piecewise_linear",
        points=[[float(t), float(v)] for t, v in zip(temps, vals, strict=True)],
        residual_rms=0.0,
        loo_residual_rms=float(np.sqrt(np.mean(loo**2))),
        loo_residual_max=float(np.max(np.abs(loo))),
    )


def polynomial(temps_c: Sequence[float], values: Sequence[float],
               degree: int = 2) -> CompensationTable:
    """Least-squares polynomial in temperature; in-sample and leave-one-out residuals."""
    if degree < 0:
        raise ValueError(f"polynomial degree must be >= 0, got {degree}")
    temps, vals = _sorted_points(temps_c, values, minimum=degree + 2)
    coeffs = np.polyfit(temps, vals, degree)
    fitted = np.polyval(coeffs, temps)
    loo = np.empty(temps.size)
    for i in range(temps.size):
        keep = np.arange(temps.size) != i
        loo[i] = vals[i] - np.polyval(np.polyfit(temps[keep], vals[keep], degree), temps[i])
    return CompensationTable(
        kind=f"polynomial_deg{degree}",
        points=[[float(t), float(v)] for t, v in zip(temps, fitted, strict=True)],
        residual_rms=float(np.sqrt(np.mean((vals - fitted) ** 2))),
        loo_residual_rms=float(np.sqrt(np.mean(loo**2))),
        loo_residual_max=float(np.max(np.abs(loo))),
        coefficients=[float(c) for c in coeffs],
    )


def tables_json(points: Sequence[Sequence[float]]) -> dict[str, Any] | None:
    """Piecewise-linear and polynomial tables of (temperature, value) points, as results.json
    gives them (with leave-one-out residuals); None below 3 finite points."""
    if len(points) < 3 or not all(np.isfinite(v) for _, v in points):
        return None
    temps = [p[0] for p in points]
    values = [p[1] for p in points]
    out = {}
    for table in (piecewise_linear(temps, values),
                  polynomial(temps, values, degree=min(2, len(points) - 2))):
        out[table.kind] = {"points": table.to_pairs(), "coefficients": table.coefficients,
                           "residual_rms": table.residual_rms,
                           "loo_residual_rms": table.loo_residual_rms,
                           "loo_residual_max": table.loo_residual_max}
    return out
