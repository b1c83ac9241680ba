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
from typing import Any

import numpy as np

from gyrocal.models.gravity import STANDARD_GRAVITY_MPS2
from gyrocal.models.gyro_model import _mapping, _number, _reject_unknown, _Where

AXES = ("x", "y", "z")
_PAIRS = tuple(f"{a}{b}" for a in AXES for b in AXES if a != b)
AXIS_KEYS = ("bias_mg", "bias_tempco_mg_per_c", "sf_error_ppm", "sf_tempco_ppm_per_c",
             "vrw_mps_per_rth")
SECTION_KEYS = ("axes", "misalignment_urad", "misalignment_tempco_urad_per_c")


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


def _pairs(data: Any, path: tuple, where: _Where) -> np.ndarray:
    out = np.zeros((3, 3))
    if data is None:
        return out
    for pair, raw in _mapping(data, path, where).items():
        if pair not in _PAIRS:
            raise where.error((*path, pair), f"unknown element; elements are {', '.join(_PAIRS)} "
                              "(row axis senses column axis)")
        out[AXES.index(pair[0]), AXES.index(pair[1])] = _number(raw, (*path, pair), where)
    return out


def parse_accelerometers(data: Any, reference_temp_c: float, where: _Where) -> AccelerometerModel:
    """The ``accelerometers`` section; errors name file, line and key path."""
    top = ("accelerometers",)
    section = _mapping(data, top, where)
    _reject_unknown(section, SECTION_KEYS, top, where)
    if "axes" not in section:
        raise where.error((*top, "axes"), "missing required key (x, y and z accelerometers)")
    axes = _mapping(section["axes"], (*top, "axes"), where)
    _reject_unknown(axes, AXES, (*top, "axes"), where)
    values = {key: np.zeros(3) for key in AXIS_KEYS}
    for i, name in enumerate(AXES):
        path = (*top, "axes", name)
        if name not in axes:
            raise where.error(path, "missing axis")
        raw = _mapping(axes[name], path, where)
        _reject_unknown(raw, AXIS_KEYS, path, where)
        for key, value in raw.items():
            number = _number(value, (*path, key), where)
            if key == "vrw_mps_per_rth" and number < 0:
                raise where.error((*path, key), f"must be >= 0, got {number:g}")
            values[key][i] = number
    return AccelerometerModel(
        **values,
        misalignment_urad=_pairs(section.get("misalignment_urad"), (*top, "misalignment_urad"), where),
        misalignment_tempco_urad_per_c=_pairs(section.get("misalignment_tempco_urad_per_c"),
                                              (*top, "misalignment_tempco_urad_per_c"), where),
        reference_temp_c=reference_temp_c)
