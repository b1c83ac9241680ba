"""Three-axis IMU gyro model (model file version 2) and the mounting geometry.

The vendor notes (seeds/003, "Measurement Error and Calibration of FOG IMU")
write the angular-rate channel of a FOG IMU as bias, scale factor and
installation (misalignment) coefficients E_ij per axis. Here each axis keeps
the whole single-axis contract of ``gyro-model.md`` (bias, scale-factor
error, their temperature coefficients, noise, catalogue effects) and the
axes are coupled by an input-referred misalignment matrix:

    ω_in,i  = ω_i + Σ_{j≠i} E_ij(T)·ω_j            (rad per rad, E_ij in µrad in the file)
    E_ij(T) = E_ij + Ė_ij·(T − T0)
    output_i = axis model i applied to ω_in,i       (gyro-model.md equation)

so the sensitivity matrix S_ij = ∂output_i/∂ω_j is scale_factor_i·(1 + s_i(T))
on the diagonal and that times E_ij off it, and E_ij = S_ij / S_ii is what
the calibration recovers. The Earth rate of an IMU is a vector (its
direction depends on the mounting and the table angle), so it enters the
input ω and no axis may declare ``earth_rate_dph``.

File layout (version 1 files stay single-axis, read by ``gyro_model.py``)::

    version: 2
    name: FOG IMU
    output_units: deg/s
    reference_temp_c: 25.0
    axes:
      x: {scale_factor: 1.0, bias_dph: 1.5, sf_error_ppm: 120, noise: {...}}
      y: {...}
      z: {...}
    misalignment_urad: {xy: 150, xz: -80, yx: 60, yz: 40, zx: -30, zy: 90}
    misalignment_tempco_urad_per_c: {xy: 0.5}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.inputs import KeyPath
from gyrocal.models.gyro_model import (
    GyroModel,
    data_context,
    model_number,
    output_units,
    raise_problems,
    read_document,
    read_model,
)
from gyrocal.models.imu_accel import AccelerometerModel, read_accelerometers, read_pair_matrix
from gyrocal.schema import Context, Fields
from gyrocal.units import UnitError

AXES = ("x", "y", "z")
EARTH_RATE_DPH = 15.041067          # sidereal rotation, deg/h (gyro-model.md)


def axis_index(name: str) -> int:
    """``x`` → 0, ``y`` → 1, ``z`` → 2."""
    return AXES.index(name)


@dataclass(frozen=True)
class ImuModel:
    """Three single-axis models coupled by an input-referred misalignment matrix."""

    axes: tuple[GyroModel, GyroModel, GyroModel]
    misalignment_urad: np.ndarray            # (3, 3), E_ij at reference_temp_c, zero diagonal
    misalignment_tempco_urad_per_c: np.ndarray
    reference_temp_c: float = 0.0
    name: str = ""
    output_units: str = "deg/s"
    #: the accelerometer triad (``imu_accel.py``); None: the file declares none (reads ideal)
    accelerometers: AccelerometerModel | None = None

    def misalignment_rad(self, temp_c: float) -> np.ndarray:
        """E(T) in rad (3 × 3, zero diagonal)."""
        e = self.misalignment_urad + self.misalignment_tempco_urad_per_c * (temp_c - self.reference_temp_c)
        return e * 1e-6

    def scale_factor(self, temp_c: float) -> np.ndarray:
        """Per-axis output units per deg/s at a sensor temperature: scale_factor·(1 + s(T))."""
        return np.array([m.scale_factor * (1.0 + 1e-6 * (m.sf_error_ppm + m.sf_tempco_ppm_per_c
                                                          * (temp_c - m.reference_temp_c)))
                         for m in self.axes])

    def sensitivity(self, temp_c: float) -> np.ndarray:
        """S(T) = diag(scale factor)·(I + E): output units per deg/s of body rate."""
        return self.scale_factor(temp_c)[:, None] * (np.eye(3) + self.misalignment_rad(temp_c))

    def bias_dph(self, temp_c: float) -> np.ndarray:
        """Input-referred bias vector (without Earth rate), deg/h."""
        return np.array([m.bias_dph + m.bias_tempco_dph_per_c * (temp_c - m.reference_temp_c)
                         for m in self.axes])


# --------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class Mounting:
    """Which IMU axis points up along the table axis, and its sign.

    The IMU frame in the table frame (x, y horizontal and turning with the
    table, z up along its axis): axis ``a`` is ``sign``·z, the next axis in
    cyclic order is the table's x and the last is ``sign``·y, which keeps the
    frame right-handed. Only the up axis matters for the calibration; the
    horizontal two see the horizontal Earth rate turn with the table, which
    whole revolutions average out.
    """

    up_axis: int       # 0, 1, 2
    sign: float        # +1 or -1

    @classmethod
    def parse(cls, text: str) -> Mounting:
        """``+x``, ``-y``, ``z`` (a bare axis is +)."""
        text = text.strip().lower()
        sign = -1.0 if text.startswith("-") else 1.0
        axis = text.lstrip("+-")
        if axis not in AXES or len(text) - len(axis) > 1:
            raise ValueError(f"must be an IMU axis with an optional sign (+x, -y, z), got {text!r}")
        return cls(axis_index(axis), sign)

    @property
    def label(self) -> str:
        return f"{'+' if self.sign > 0 else '-'}{AXES[self.up_axis].upper()}"

    def up_vector(self) -> np.ndarray:
        """The table axis (up) in IMU coordinates."""
        u = np.zeros(3)
        u[self.up_axis] = self.sign
        return u

    def imu_from_table(self) -> np.ndarray:
        """Rows: the IMU axes in table coordinates (a proper rotation)."""
        z_up, x_t, y_t = np.array([0.0, 0, 1]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
        a = self.up_axis
        rows = np.zeros((3, 3))
        rows[a] = self.sign * z_up
        rows[(a + 1) % 3] = x_t
        rows[(a + 2) % 3] = self.sign * y_t
        return rows


def earth_rate_table_dps(latitude_deg: float, table_angle_deg: np.ndarray) -> np.ndarray:
    """Earth rate in the turning table frame, deg/s, shape (n, 3).

    World frame east-north-up: Ω·(0, cos φ, sin φ). The table frame is the
    world frame turned by the table angle θ about up (counter-clockwise seen
    from the top), so a world vector reads R_z(−θ)·v in it.
    """
    omega = EARTH_RATE_DPH / 3600.0
    lat = math.radians(latitude_deg)
    north, up = omega * math.cos(lat), omega * math.sin(lat)
    theta = np.radians(np.asarray(table_angle_deg, dtype=float))
    return np.stack([north * np.sin(theta), north * np.cos(theta), np.full_like(theta, up)], axis=-1)


def body_rate_dps(mounting: Mounting, table_rate_dps: np.ndarray, table_angle_deg: np.ndarray,
                  latitude_deg: float) -> np.ndarray:
    """True angular rate in IMU axes (n, 3), deg/s: table rate plus Earth rate."""
    table = earth_rate_table_dps(latitude_deg, table_angle_deg)
    table[:, 2] += np.asarray(table_rate_dps, dtype=float)
    return table @ mounting.imu_from_table().T


def specific_force_imu_g(mounting: Mounting, gravity_g: float) -> np.ndarray:
    """What a perfect accelerometer triad at rest reads in ``mounting``: gravity's reaction, up.

    The table axis is vertical, so the specific force is +gravity along it in
    the table frame whatever the table angle; the IMU sits at the table's
    centre, so turning adds no centripetal term (an offset r would add ω²r).
    """
    return mounting.up_vector() * float(gravity_g)


def vertical_earth_rate_dps(latitude_deg: float) -> float:
    return EARTH_RATE_DPH / 3600.0 * math.sin(math.radians(latitude_deg))


# --------------------------------------------------------------------------- file


def _axis_models(ctx: Context, raw: object,
                 inherited: dict[str, object]) -> list[GyroModel | None] | None:
    """Each of x, y, z as a single-axis model, with the file's inherited keys."""
    path: KeyPath = ("axes",)
    axes = Fields(ctx, path, raw, "axes")
    if not axes.valid:
        return None
    models: list[GyroModel | None] = []
    for name in AXES:
        present, axis_raw = axes.raw(name)
        if not present:
            ctx.report((*path, name), "missing axis")
            models.append(None)
            continue
        if isinstance(axis_raw, Mapping) and "earth_rate_dph" in axis_raw:
            ctx.report((*path, name, "earth_rate_dph"),
                       "an IMU's Earth rate is a vector set by the mounting and the station "
                       "latitude; leave it out of the axes")
        data = {"version": 1, **inherited, **axis_raw} if isinstance(axis_raw, Mapping) else axis_raw
        models.append(read_model(ctx, (*path, name), data))
    for name in axes.data:
        if name not in AXES:
            axes.used.add(name)
            ctx.report((*path, name), "unknown axis; axes are x, y, z")
    return models


def _imu_version(value: object) -> int:
    if value != 2 or isinstance(value, bool):
        raise UnitError(f"a three-axis model is version 2, got {value!r}")
    return 2


def read_imu_model(ctx: Context, data: object) -> ImuModel | None:
    """A version-2 model; None when anything was wrong (every problem is in ``ctx``)."""
    top = Fields(ctx, (), data if data is not None else {}, "a model")
    if not top.valid:
        return None
    before = len(ctx.problems)
    top.take("version", _imu_version)
    name = top.take("name", lambda value: str(value or ""), required=False, default="")
    units = top.take("output_units", output_units, required=False)
    reference = top.take("reference_temp_c", model_number, required=False)
    # the axes inherit the file's units and reference temperature (reported once, here)
    inherited = {key: value for key, value in (("output_units", units),
                                               ("reference_temp_c", reference)) if value is not None}
    present, axes_raw = top.raw("axes")
    if not present:
        ctx.report(("axes",), "required key is missing (x, y and z single-axis models)")
    models = _axis_models(ctx, axes_raw, inherited) if present else None
    matrices = {key: read_pair_matrix(ctx, (key,), top.raw(key)[1])
                for key in ("misalignment_urad", "misalignment_tempco_urad_per_c")}
    reference_c = reference if reference is not None else 0.0
    present, acc_raw = top.raw("accelerometers")
    accelerometers = None if acc_raw is None else read_accelerometers(ctx, acc_raw, reference_c)
    top.finish()
    if len(ctx.problems) > before or models is None or None in models:
        return None
    return ImuModel(axes=(models[0], models[1], models[2]), **matrices,  # type: ignore[arg-type]
                    reference_temp_c=reference_c, name=name, output_units=models[0].output_units,
                    accelerometers=accelerometers)


def parse_imu_model(data: Any, source: str = "<model>",
                    lines: dict[tuple, int] | None = None) -> ImuModel:
    """Validate a version-2 model given as plain data; errors name file, line and key path."""
    ctx = data_context(source, lines)
    model = read_imu_model(ctx, data)
    raise_problems(ctx)
    assert model is not None
    return model


def load_any_model(path: str | Path) -> GyroModel | ImuModel:
    """A model file of either version: 1 → single axis (unchanged), 2 → three-axis IMU."""
    document = read_document(path)
    ctx = Context(document)
    data = document.data
    if isinstance(data, Mapping) and data.get("version") == 2:
        model: GyroModel | ImuModel | None = read_imu_model(ctx, data)
    else:
        model = read_model(ctx, (), data)
    raise_problems(ctx)
    assert model is not None
    return model
