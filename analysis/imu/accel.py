"""Accelerometer bias, scale factors and misalignment from gravity: the multi-position method.

IEEE Std 1293 (linear accelerometers, static multi-position test) applied to
the hexahedron fixture of the vendor notes (seeds/003): at each temperature
each IMU axis points up and then down along the (vertical) table axis, the
table at rest. With axis ``a`` up (sign s) the specific force in IMU axes
is u·g with u = s·e_a and g the local gravity in standard g
(``models/gravity.py``), so every static mean obeys

    mean_i = b_i + Σ_j K_ij · u_j · g                       (g)

one linear least-squares problem per accelerometer over the six positions
at one temperature (4 unknowns, 6 equations): b_i is the bias (the mean of
all six), K_ii the scale factor (half the up − down difference over g) and
M_ij = K_ij / K_ii the misalignment (``models/imu_accel.py``'s definition).

Uncertainty (GUM):

* type A: each static mean carries the standard uncertainty of its block
  means (20 blocks, so correlated noise is not under-counted); it is
  propagated through the least-squares weights, then scaled by the Birge
  ratio √(χ²/dof) when the six positions scatter more than their own noise
  says (a model the data do not follow is never hidden by a small u);
* type B: the local gravity (relative standard uncertainty u_g), which
  scales every K_ij but cancels in M_ij and leaves b alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrocal.models.imu_model import Mounting

#: blocks a static is cut into for the uncertainty of its mean
BLOCKS = 20


@dataclass(frozen=True)
class AccStatic:
    """One static of an accelerometer calibration: its three means and their uncertainties."""

    step_id: str
    temp_index: int
    setpoint_c: float
    temp_c: float
    mounting: Mounting
    mean_g: np.ndarray           # (3,)
    u_mean_g: np.ndarray         # (3,) standard uncertainty of each mean
    n_samples: int


def static_mean(samples: np.ndarray) -> tuple[float, float]:
    """Mean and its standard uncertainty from the scatter of :data:`BLOCKS` block means."""
    data = np.asarray(samples, dtype=float)
    n = data.size // BLOCKS * BLOCKS
    if n < BLOCKS * 2:
        raise ValueError(f"a static needs at least {BLOCKS * 2} samples, got {data.size}")
    blocks = data[:n].reshape(BLOCKS, -1).mean(axis=1)
    return float(data.mean()), float(blocks.std(ddof=1) / np.sqrt(BLOCKS))


@dataclass(frozen=True)
class AccelFit:
    """The accelerometer calibration at one temperature."""

    temp_index: int
    setpoint_c: float
    temp_c: float
    sensitivity: np.ndarray      # K (3, 3): output g per g of specific force along j
    u_sensitivity_a: np.ndarray  # type A standard uncertainty of each K_ij
    bias_g: np.ndarray           # (3,)
    u_bias_g: np.ndarray
    dof: int
    birge_ratio: np.ndarray      # (3,) √(χ²/dof) per accelerometer (1 when dof is 0)
    residuals: np.ndarray        # (n, 3) g
    statics: tuple[AccStatic, ...]
    gravity_g: float
    u_gravity_rel: float         # relative standard uncertainty of the local gravity

    @property
    def scale_factor(self) -> np.ndarray:
        return np.diag(self.sensitivity).copy()

    @property
    def u_scale_factor(self) -> np.ndarray:
        """Type A and gravity (type B) combined."""
        a = np.diag(self.u_sensitivity_a)
        return np.sqrt(a**2 + (self.scale_factor * self.u_gravity_rel) ** 2)

    @property
    def misalignment_rad(self) -> np.ndarray:
        m = self.sensitivity / self.scale_factor[:, None]
        np.fill_diagonal(m, 0.0)
        return m

    @property
    def u_misalignment_rad(self) -> np.ndarray:
        u = self.u_sensitivity_a / np.abs(self.scale_factor)[:, None]
        np.fill_diagonal(u, 0.0)
        return u

    def input_force_g(self, static: AccStatic) -> np.ndarray:
        return static.mounting.up_vector() * self.gravity_g


def fit_accelerometers(statics: Sequence[AccStatic], gravity_g: float,
                       u_gravity_rel: float) -> AccelFit:
    """Weighted LS of K and b at one temperature; an axis never up or down leaves NaN."""
    if not statics:
        raise ValueError("no statics at this temperature")
    x = np.array([s.mounting.up_vector() * gravity_g for s in statics])
    y = np.array([s.mean_g for s in statics])
    u = np.array([s.u_mean_g for s in statics])
    seen = np.flatnonzero(np.any(x != 0.0, axis=0))
    design = np.column_stack([np.ones(len(statics)), x[:, seen]])
    n, p = design.shape
    if n < p or np.linalg.matrix_rank(design) < p:
        raise ValueError(f"{n} statics do not separate bias from scale factor: each axis needs "
                         "an up and a down position")
    weights = np.linalg.pinv(design)                       # (p, n): coef = weights @ y
    coef = weights @ y
    residuals = y - design @ coef
    dof = n - p
    u_coef = np.sqrt((weights**2) @ (u**2))                # (p, 3) propagated dwell noise
    birge = np.ones(3)
    if dof > 0:
        chi2 = np.sum((residuals / np.where(u > 0, u, np.inf)) ** 2, axis=0)
        birge = np.maximum(1.0, np.sqrt(chi2 / dof))
    u_coef = u_coef * birge
    sensitivity = np.full((3, 3), np.nan)
    u_sens = np.full((3, 3), np.nan)
    sensitivity[:, seen] = coef[1:].T
    u_sens[:, seen] = u_coef[1:].T
    temps = np.array([s.temp_c for s in statics])
    return AccelFit(
        temp_index=statics[0].temp_index, setpoint_c=statics[0].setpoint_c,
        temp_c=float(np.average(temps, weights=[s.n_samples for s in statics])),
        sensitivity=sensitivity, u_sensitivity_a=u_sens, bias_g=coef[0].copy(),
        u_bias_g=u_coef[0].copy(), dof=dof, birge_ratio=birge, residuals=residuals,
        statics=tuple(statics), gravity_g=float(gravity_g), u_gravity_rel=float(u_gravity_rel))


def fit_all_accelerometers(statics: Sequence[AccStatic], gravity_g: float,
                           u_gravity_rel: float) -> list[AccelFit]:
    """One fit per temperature step, in the plan's order."""
    by_temp: dict[int, list[AccStatic]] = {}
    for s in statics:
        by_temp.setdefault(s.temp_index, []).append(s)
    return [fit_accelerometers(by_temp[k], gravity_g, u_gravity_rel) for k in sorted(by_temp)]


def compensate_force(sensitivity: np.ndarray, bias_g: np.ndarray, mean_g: np.ndarray) -> np.ndarray:
    """Specific force from outputs with a calibration: K⁻¹·(output − b), g."""
    return np.linalg.solve(sensitivity, np.asarray(mean_g, dtype=float) - bias_g)
