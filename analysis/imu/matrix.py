"""The three-axis scale-factor/misalignment matrix and bias vector from ± rate dwells.

The vendor notes' method (seeds/003): at each temperature the IMU is turned
so that X, Y and Z in turn lie along the table axis, and the table turns
each way at each rate. With the IMU axis ``a`` up (sign s) and the table at
ω, the body rate is u·(ω + Ω_v) with u = s·e_a and Ω_v the vertical Earth
rate; the horizontal Earth rate turns with the table and averages out over
the whole revolutions each dwell is trimmed to. So every dwell mean obeys

    mean_i = b_i + Σ_j S_ij · u_j · (ω + Ω_v)          (output units)

one linear least-squares problem per output axis i, over all mountings and
rates at one temperature, unknowns b_i and the row S_i·. The scale factor is
S_ii; the misalignment E_ij = S_ij / S_ii (rad, the model's input-referred
definition in ``models/imu_model.py``); the input-referred bias is S⁻¹·b.
Standard uncertainties are the LS (type A) ones: residual variance with
n − 4 degrees of freedom times (XᵀX)⁻¹.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrocal.models.imu_model import Mounting, vertical_earth_rate_dps


@dataclass(frozen=True)
class ImuDwell:
    """One completed dwell of an IMU calibration, reduced to its three axis means."""

    step_id: str
    temp_index: int
    setpoint_c: float
    temp_c: float                # measured (sensor, else chamber) mean temperature
    mounting: Mounting
    rate_dps: float              # signed table rate
    mean_xyz: np.ndarray         # (3,) output units, over whole revolutions
    n_samples: int


@dataclass(frozen=True)
class MatrixFit:
    """The calibration at one temperature."""

    temp_index: int
    setpoint_c: float
    temp_c: float
    sensitivity: np.ndarray      # S (3, 3): output units per deg/s of body rate
    u_sensitivity: np.ndarray    # standard uncertainty of each S_ij (type A)
    bias_output: np.ndarray      # b (3,): output units
    u_bias_output: np.ndarray
    dof: int
    residuals: np.ndarray        # (n, 3) dwell residuals, output units
    dwells: tuple[ImuDwell, ...]
    earth_vertical_dps: float    # the vertical Earth rate added to every dwell's input

    @property
    def scale_factor(self) -> np.ndarray:
        return np.diag(self.sensitivity).copy()

    @property
    def u_scale_factor(self) -> np.ndarray:
        return np.diag(self.u_sensitivity).copy()

    @property
    def misalignment_rad(self) -> np.ndarray:
        e = self.sensitivity / self.scale_factor[:, None]
        np.fill_diagonal(e, 0.0)
        return e

    @property
    def u_misalignment_rad(self) -> np.ndarray:
        u = self.u_sensitivity / np.abs(self.scale_factor)[:, None]
        np.fill_diagonal(u, 0.0)
        return u

    @property
    def bias_dph(self) -> np.ndarray:
        """Input-referred bias vector S⁻¹·b (Earth rate removed), deg/h."""
        return np.linalg.solve(self.sensitivity, self.bias_output) * 3600.0

    @property
    def u_bias_dph(self) -> np.ndarray:
        return self.u_bias_output / np.abs(self.scale_factor) * 3600.0

    def axis_linearity(self, axis: int) -> dict[str, float | None]:
        """Nonlinearity (residual along the up axis) and asymmetry (+ vs − slope) of one axis."""
        up = [(d, r[axis]) for d, r in zip(self.dwells, self.residuals, strict=True)
              if d.mounting.up_axis == axis]
        if not up:
            return {"nonlinearity_rms_pct": None, "nonlinearity_max_ppm_fs": None,
                    "asymmetry_ppm": None}
        sf = self.sensitivity[axis, axis]
        full_scale = max(abs(d.rate_dps) for d, _ in up) * abs(sf)
        res = np.array([r for _, r in up])
        slopes = {}
        for sign in (1.0, -1.0):
            side = [d for d, _ in up if np.sign(d.rate_dps) * d.mounting.sign == sign]
            x = np.array([_input(d, self.earth_vertical_dps)[axis] for d in side])
            y = np.array([d.mean_xyz[axis] - _cross(self.sensitivity, d, axis,
                                                    self.earth_vertical_dps) for d in side])
            if len(set(np.round(x, 9))) >= 2:
                # each side's own line (slope and intercept): the asymmetry is the slope
                # difference alone, not pulled by a bias that the other side shares
                slopes[sign] = float(np.polyfit(x, y, 1)[0])
            elif len(x):
                slopes[sign] = float(np.dot(x, y - self.bias_output[axis]) / np.dot(x, x))
        asym = None
        if len(slopes) == 2:
            asym = (slopes[1.0] - slopes[-1.0]) / (0.5 * (slopes[1.0] + slopes[-1.0])) * 1e6
        return {"nonlinearity_rms_pct": float(np.sqrt(np.mean(res**2)) / full_scale * 100),
                "nonlinearity_max_ppm_fs": float(np.max(np.abs(res)) / full_scale * 1e6),
                "asymmetry_ppm": asym}


def _input(dwell: ImuDwell, earth_vertical_dps: float = 0.0) -> np.ndarray:
    return dwell.mounting.up_vector() * (dwell.rate_dps + earth_vertical_dps)


def _cross(sensitivity: np.ndarray, dwell: ImuDwell, axis: int, earth_dps: float) -> float:
    """What the other axes' inputs put on ``axis`` (zero unless the up vector has them)."""
    x = _input(dwell, earth_dps)
    return float(sum(sensitivity[axis, j] * x[j] for j in range(3) if j != axis))


def fit_temperature(dwells: Sequence[ImuDwell], latitude_deg: float) -> MatrixFit:
    """LS fit of S and b at one temperature from all its dwells (every mounting, every rate).

    An axis never mounted up leaves its column undetermined: NaN, never a guess.
    """
    if not dwells:
        raise ValueError("no dwells at this temperature")
    earth_dps = vertical_earth_rate_dps(latitude_deg)
    x = np.array([_input(d, earth_dps) for d in dwells])           # (n, 3) body rate, deg/s
    y = np.array([d.mean_xyz for d in dwells], dtype=float)         # (n, 3) outputs
    seen = np.flatnonzero(np.any(x != 0.0, axis=0))
    design = np.column_stack([np.ones(len(dwells)), x[:, seen]])
    n, p = design.shape
    if n <= p:
        raise ValueError(f"{n} dwells for {p} unknowns per axis: need ± rates in every mounting")
    coef, _, rank, _ = np.linalg.lstsq(design, y, rcond=None)
    if rank < p:
        raise ValueError("the dwells do not separate bias from scale factor (one rate, one sign?)")
    residuals = y - design @ coef
    dof = n - p
    variance = np.sum(residuals**2, axis=0) / dof                   # per output axis
    cov_unit = np.linalg.inv(design.T @ design)
    sensitivity = np.full((3, 3), np.nan)
    u_sensitivity = np.full((3, 3), np.nan)
    sensitivity[:, seen] = coef[1:].T
    u_sensitivity[:, seen] = np.sqrt(np.outer(variance, np.diag(cov_unit)[1:]))
    temps = np.array([d.temp_c for d in dwells])
    return MatrixFit(
        temp_index=dwells[0].temp_index, setpoint_c=dwells[0].setpoint_c,
        temp_c=float(np.average(temps, weights=[d.n_samples for d in dwells])),
        sensitivity=sensitivity, u_sensitivity=u_sensitivity,
        bias_output=coef[0].copy(), u_bias_output=np.sqrt(variance * cov_unit[0, 0]),
        dof=dof, residuals=residuals, dwells=tuple(dwells), earth_vertical_dps=earth_dps)


def fit_all(dwells: Sequence[ImuDwell], latitude_deg: float) -> list[MatrixFit]:
    """One fit per temperature step, in the plan's order."""
    by_temp: dict[int, list[ImuDwell]] = {}
    for d in dwells:
        by_temp.setdefault(d.temp_index, []).append(d)
    return [fit_temperature(by_temp[k], latitude_deg) for k in sorted(by_temp)]


def compensate(sensitivity: np.ndarray, bias_output: np.ndarray, mean_xyz: np.ndarray) -> np.ndarray:
    """Body rate from outputs with a calibration: S⁻¹·(output − b), deg/s."""
    return np.linalg.solve(sensitivity, np.asarray(mean_xyz, dtype=float) - bias_output)
