"""The accelerometer triad of an IMU model file (version 2, key ``accelerometers``).

The vendor notes (seeds/003, "Measurement Error and Calibration of FOG IMU",
§3.2) write the acceleration channel like the angular-rate one: per axis a
zero deviation (bias), a scale factor and installation coefficients M_ij.
Here, in the same input-referred form as the gyro triad (``imu_model.py``):

    f_in,i   = f_i + Σ_{j≠i} M_ij(T)·f_j                 (M_ij in µrad in the file)
    output_i = (1 + k_i(T))·f_in,i + b_i(T) + noise       (g, the standard 9.80665 m/s²)
    k_i(T)   = (sf_error_ppm + sf_tempco_ppm_per_c·(T − T0))·1e-6
    b_i(T)   = (bias_mg + bias_tempco_mg_per_c·(T − T0))·1e-3
    M_ij(T)  = M_ij + Ṁ_ij·(T − T0)

so K = ∂output/∂f = diag(1 + k)·(I + M), and M_ij = K_ij / K_ii is what the
calibration recovers. The noise is white, given as velocity random walk
(m/s/√h, as datasheets give it): per sample σ = VRW/60·√fs / 9.80665 g.
File layout::

    accelerometers:
      axes:
        x: {bias_mg: 1.2, bias_tempco_mg_per_c: 0.01, sf_error_ppm: 300,
            sf_tempco_ppm_per_c: 15, vrw_mps_per_rth: 0.07}
        y: {...}
        z: {...}
      misalignment_urad: {xy: 400, ...}
      misalignment_tempco_urad_per_c: {xy: 2.0}
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrocal.inputs import KeyPath
from gyrocal.models.gravity import STANDARD_GRAVITY_MPS2
from gyrocal.models.gyro_model import model_number, non_negative
from gyrocal.schema import Context, Fields

AXES = ("x", "y", "z")
PAIRS = tuple(f"{a}{b}" for a in AXES for b in AXES if a != b)
AXIS_KEYS = ("bias_mg", "bias_tempco_mg_per_c", "sf_error_ppm", "sf_tempco_ppm_per_c",
             "vrw_mps_per_rth")


@dataclass(frozen=True)
class AccelerometerModel:
    """Three accelerometers: per-axis bias, scale factor, noise; coupled by M_ij."""

    bias_mg: np.ndarray                       # (3,) at reference_temp_c
    bias_tempco_mg_per_c: np.ndarray
    sf_error_ppm: np.ndarray
    sf_tempco_ppm_per_c: np.ndarray
    vrw_mps_per_rth: np.ndarray
    misalignment_urad: np.ndarray             # (3, 3), zero diagonal
    misalignment_tempco_urad_per_c: np.ndarray
    reference_temp_c: float = 0.0

    def _dt(self, temp_c: float) -> float:
        return float(temp_c) - self.reference_temp_c

    def bias_g(self, temp_c: float) -> np.ndarray:
        return (self.bias_mg + self.bias_tempco_mg_per_c * self._dt(temp_c)) * 1e-3

    def scale_factor(self, temp_c: float) -> np.ndarray:
        """1 + k_i(T): output g per g of specific force along the axis."""
        return 1.0 + (self.sf_error_ppm + self.sf_tempco_ppm_per_c * self._dt(temp_c)) * 1e-6

    def misalignment_rad(self, temp_c: float) -> np.ndarray:
        return (self.misalignment_urad + self.misalignment_tempco_urad_per_c * self._dt(temp_c)) * 1e-6

    def sensitivity(self, temp_c: float) -> np.ndarray:
        """K(T) = diag(1 + k)·(I + M): output g per g of specific force about each axis."""
        return self.scale_factor(temp_c)[:, None] * (np.eye(3) + self.misalignment_rad(temp_c))

    def noise_sigma_g(self, fs_hz: float) -> np.ndarray:
        """White-noise standard deviation per sample at ``fs_hz``, g."""
        return self.vrw_mps_per_rth / 60.0 * math.sqrt(fs_hz) / STANDARD_GRAVITY_MPS2

    def indicate(self, force_g: np.ndarray, temp_c: float, fs_hz: float,
                 rng: np.random.Generator) -> np.ndarray:
        """Outputs (n, 3) g for true specific force (n, 3) g at one temperature."""
        force_g = np.asarray(force_g, dtype=float)
        out = force_g @ self.sensitivity(temp_c).T + self.bias_g(temp_c)
        return out + rng.standard_normal(force_g.shape) * self.noise_sigma_g(fs_hz)


def read_pair_matrix(ctx: Context, path: KeyPath, raw: object) -> np.ndarray | None:
    """A misalignment mapping ``{xy: 150, ...}`` as a 3 × 3 matrix (zero diagonal); the row
    axis senses the column axis. None when an element was wrong (reported)."""
    out = np.zeros((3, 3))
    if raw is None:
        return out
    entries = Fields(ctx, path, raw, str(path[-1]))
    complete = entries.valid
    for pair in list(entries.data):
        if pair not in PAIRS:
            entries.used.add(pair)
            ctx.report((*path, pair), f"unknown element; elements are {', '.join(PAIRS)} "
                       "(row axis senses column axis)")
            complete = False
            continue
        value = entries.take(pair, model_number)
        if value is None:
            complete = False
        else:
            out[AXES.index(pair[0]), AXES.index(pair[1])] = value
    return out if complete else None


def _read_axes(ctx: Context, path: KeyPath, raw: object) -> dict[str, np.ndarray] | None:
    axes = Fields(ctx, path, raw, "axes")
    values = {key: np.zeros(3) for key in AXIS_KEYS}
    complete = axes.valid
    for i, name in enumerate(AXES):
        present, axis_raw = axes.raw(name)
        if not present:
            if axes.valid:
                ctx.report((*path, name), "missing axis")
            complete = False
            continue
        axis = Fields(ctx, (*path, name), axis_raw, "an accelerometer axis")
        for key in AXIS_KEYS:
            convert = non_negative if key == "vrw_mps_per_rth" else model_number
            value = axis.take(key, convert, required=False, default=0.0)
            if value is None:
                complete = False
            else:
                values[key][i] = value
        axis.finish()
        complete = complete and axis.valid
    axes.finish()
    return values if complete else None


def read_accelerometers(ctx: Context, raw: object,
                        reference_temp_c: float) -> AccelerometerModel | None:
    """The ``accelerometers`` section; None when anything in it was wrong (reported)."""
    top: KeyPath = ("accelerometers",)
    section = Fields(ctx, top, raw, "accelerometers")
    if not section.valid:
        return None
    before = len(ctx.problems)
    present, axes_raw = section.raw("axes")
    if not present:
        ctx.report((*top, "axes"), "required key is missing (x, y and z accelerometers)")
    values = _read_axes(ctx, (*top, "axes"), axes_raw) if present else None
    matrices = {key: read_pair_matrix(ctx, (*top, key), section.raw(key)[1])
                for key in ("misalignment_urad", "misalignment_tempco_urad_per_c")}
    section.finish()
    if len(ctx.problems) > before or values is None or any(m is None for m in matrices.values()):
        return None
    return AccelerometerModel(**values, **matrices, reference_temp_c=reference_temp_c)
