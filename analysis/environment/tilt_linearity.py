"""Static test of a tilt sensor (inclinometer): sensitivity, linearity, lateral sensitivity, zero stability.

The vendor notes (seeds/003, "Static Capacitance Test of MEMS Tilt Sensor"
§1.2) set n angle points over the range with an indexing head (±90° in 15°
steps; ±30° in 5° steps), take the input acceleration a_i = g·sin θ_i, and fit
the output by least squares, x = K·a + x0: K is the sensitivity, the
linearity the largest residual over the full-scale output span; the lateral
(cross-axis) sensitivity is the output's slope against acceleration across the
sensitive axis over K; the zero stability the spread of the zero output over a
stated time. This module is the analysis; the procedure that drives the table
in position mode as the indexing head is not built (no position-mode call on
main), so the points come from a log or a test.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: the vendor notes' angle points, deg
POINTS_90_DEG = tuple(range(-90, 91, 15))
POINTS_30_DEG = tuple(range(-30, 31, 5))


@dataclass(frozen=True)
class LinearityResult:
    sensitivity: float            # output units per g
    u_sensitivity: float          # standard uncertainty (LS, type A)
    zero_output: float            # x0, output units
    linearity_pct_fs: float       # max |residual| / full-scale span, %
    residuals: np.ndarray         # output units, per point


def linearity(angles_deg: Sequence[float], outputs: Sequence[float], gravity_g: float = 1.0
              ) -> LinearityResult:
    """LS line of output against input acceleration g·sin θ at the angle points."""
    theta = np.radians(np.asarray(angles_deg, dtype=float))
    x = np.asarray(outputs, dtype=float)
    if theta.size < 3 or theta.size != x.size:
        raise ValueError(f"need ≥ 3 angle points with one output each, got {theta.size} and {x.size}")
    a = gravity_g * np.sin(theta)
    design = np.column_stack([a, np.ones_like(a)])
    coef, *_ = np.linalg.lstsq(design, x, rcond=None)
    residuals = x - design @ coef
    dof = x.size - 2
    s2 = float(residuals @ residuals / dof) if dof > 0 else 0.0
    u_k = float(np.sqrt(s2 * np.linalg.inv(design.T @ design)[0, 0]))
    span = abs(coef[0]) * (a.max() - a.min())
    return LinearityResult(float(coef[0]), u_k, float(coef[1]),
                           float(np.max(np.abs(residuals)) / span * 100.0), residuals)


def lateral_sensitivity_pct(cross_angles_deg: Sequence[float], outputs: Sequence[float],
                            sensitivity: float, gravity_g: float = 1.0) -> float:
    """Slope of the output against acceleration across the sensitive axis, % of K."""
    a = gravity_g * np.sin(np.radians(np.asarray(cross_angles_deg, dtype=float)))
    slope = np.polyfit(a, np.asarray(outputs, dtype=float), 1)[0]
    return float(abs(slope) / abs(sensitivity) * 100.0)


def zero_stability(zero_outputs: Sequence[float], sensitivity: float) -> float:
    """Standard deviation of the zero output over the record, in g of input."""
    x = np.asarray(zero_outputs, dtype=float)
    if x.size < 2:
        raise ValueError("zero stability needs at least two readings")
    return float(np.std(x, ddof=1) / abs(sensitivity))
