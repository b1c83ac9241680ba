"""Magnetic (Faraday) bias sensitivity of a FOG from static dwells at ±B and 0.

The vendor notes (seeds/003, "Magnetic Sensitivity of FOG IMU") quote the
bias sensitivity in °/(h·T): about 10⁴ for an unshielded FOG, 1–10 required
for navigation-grade systems. With a Helmholtz coil along one axis (field
B = coil constant (T/A) × current), the bias of each static is regressed on
B by weighted least squares; the slope is the sensitivity and its standard
uncertainty combines the dwells' own (propagated) with the coil constant's
relative uncertainty. This module is the analysis; driving the coil through
a programmable supply is not built (no supply driver on main).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MagneticSensitivity:
    sensitivity_dph_per_t: float
    u_dph_per_t: float
    bias_at_zero_dph: float

    def grade(self) -> str:
        """Where it falls against the vendor notes' figures."""
        s = abs(self.sensitivity_dph_per_t)
        if s <= 10.0:
            return "within the 1-10 deg/(h·T) of navigation-grade systems"
        if s < 1e3:
            return "above navigation grade (1-10 deg/(h·T)), below an unshielded coil (~1e4)"
        return "of the order of an unshielded FOG (~1e4 deg/(h·T))"


def field_t(current_a: Sequence[float], coil_constant_t_per_a: float) -> np.ndarray:
    return np.asarray(current_a, dtype=float) * coil_constant_t_per_a


def sensitivity(field: Sequence[float], bias_dph: Sequence[float], u_bias_dph: Sequence[float],
                u_coil_rel: float = 0.0) -> MagneticSensitivity:
    """Weighted LS slope of bias on field (at least two distinct fields)."""
    b_t = np.asarray(field, dtype=float)
    y = np.asarray(bias_dph, dtype=float)
    u = np.asarray(u_bias_dph, dtype=float)
    if b_t.size < 2 or np.unique(b_t).size < 2 or not np.all(u > 0):
        raise ValueError("need dwells at two or more distinct fields, each with u > 0")
    w = 1.0 / u**2
    design = np.column_stack([b_t, np.ones_like(b_t)])
    cov = np.linalg.inv(design.T @ (design * w[:, None]))
    coef = cov @ design.T @ (w * y)
    u_slope = float(np.sqrt(cov[0, 0] + (coef[0] * u_coil_rel) ** 2))
    return MagneticSensitivity(float(coef[0]), u_slope, float(coef[1]))
