"""Three-axis IMU model files (version 2) and the mounting geometry.

Expected numbers are worked by hand from the file's values and the Earth
rate of gyro-model.md (15.041067 deg/h), not taken from the code.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from gyrocal.models.gyro_model import GyroModel, ModelError, load_model
from gyrocal.models.imu_model import (
    ImuModel,
    Mounting,
    body_rate_dps,
    earth_rate_table_dps,
    load_any_model,
)

REPO = Path(__file__).resolve().parents[2]
IMU_FILE = REPO / "gyro-models" / "fog-imu.yaml"


def test_the_example_imu_file_gives_the_matrix_worked_by_hand() -> None:
    model = load_any_model(IMU_FILE)
    assert isinstance(model, ImuModel)
    # at 25 °C (the reference): S_xx = 1·(1 + 150e-6), S_xy = S_xx · 250e-6
    s = model.sensitivity(25.0)
    assert s[0, 0] == pytest.approx(1.000150, abs=1e-12)
    assert s[0, 1] == pytest.approx(1.000150 * 250e-6, rel=1e-12)
    assert s[1, 2] == pytest.approx((1 - 80e-6) * 300e-6, rel=1e-12)
    # at 0 °C: sf_x = 1 + (150 + 8·(−25))·1e-6 = 0.99995; E_xy = 250 + 1.5·(−25) = 212.5 µrad
    assert model.scale_factor(0.0)[0] == pytest.approx(0.99995, abs=1e-12)
    assert model.misalignment_rad(0.0)[0, 1] == pytest.approx(212.5e-6, abs=1e-15)
    assert model.misalignment_rad(0.0)[2, 0] == pytest.approx(-220e-6, abs=1e-15)
    assert model.bias_dph(0.0)[1] == pytest.approx(-2.0 + 0.015 * 25, abs=1e-12)
    assert np.all(np.diag(model.misalignment_rad(10.0)) == 0.0)


def test_version_1_files_stay_single_axis_and_unchanged() -> None:
    path = REPO / "gyro-models" / "nominal-fog.yaml"
    assert load_any_model(path) == load_model(path)
    assert isinstance(load_any_model(path), GyroModel)


def test_a_version_2_file_where_one_axis_is_expected_says_so() -> None:
    with pytest.raises(ModelError, match=r"fog-imu.yaml:\d+: version: unsupported version 2 for a single-axis model: version 2 is a three-axis"):
        load_model(IMU_FILE)


@pytest.mark.parametrize(("edit", "message"), [
    (("    noise: {arw_deg_per_rth: 0.01, bias_instability_dph: 0.02}\n  z:",
      "    noise: {arw_deg_per_rth: -0.01, bias_instability_dph: 0.02}\n  z:"),
     r":24: axes\.y\.noise\.arw_deg_per_rth: must be >= 0"),
    (("xy: 250.0,", "xx: 250.0,"), r":32: misalignment_urad\.xx: unknown element"),
    (("    bias_dph: 0.8\n", "    bias_dph: 0.8\n    earth_rate_dph: 11.6\n"),
     r"axes\.z\.earth_rate_dph: an IMU's Earth rate is a vector"),
    (("  z:\n", "  w:\n"), r"axes\.z: missing axis"),
])
def test_model_file_errors_name_line_and_key_path(tmp_path: Path, edit: tuple[str, str],
                                                   message: str) -> None:
    text = IMU_FILE.read_text()
    assert edit[0] in text
    bad = tmp_path / "bad-imu.yaml"
    bad.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ModelError, match=r"bad-imu\.yaml" + (message if message.startswith(":")
                                                               else r".*" + message)):
        load_any_model(bad)


@pytest.mark.parametrize(("axis", "sign"), list(itertools.product(range(3), (1.0, -1.0))))
def test_every_mounting_is_a_proper_rotation_with_the_declared_axis_up(axis: int, sign: float) -> None:
    m = Mounting(axis, sign)
    r = m.imu_from_table()
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_array_equal(r @ np.array([0.0, 0.0, 1.0]), m.up_vector())


def test_mounting_text() -> None:
    assert Mounting.parse("+x") == Mounting(0, 1.0)
    assert Mounting.parse("-Z") == Mounting(2, -1.0)
    assert Mounting.parse("y").label == "+Y"
    for bad in ("w", "+-x", "xy", ""):
        with pytest.raises(ValueError):
            Mounting.parse(bad)


def test_earth_rate_components_at_the_simulated_lab() -> None:
    # 15.041067·sin(50.46°) = 11.600 deg/h up, ·cos = 9.574 deg/h north
    table = earth_rate_table_dps(50.46, np.array([0.0, 90.0])) * 3600.0
    assert table[0, 2] == pytest.approx(11.6003, abs=1e-3)
    assert table[0, 1] == pytest.approx(9.5754, abs=1e-3)     # θ = 0: table y points north
    assert table[1, 0] == pytest.approx(9.5754, abs=1e-3)     # turned 90° CCW: north is along x
    assert abs(table[1, 1]) < 1e-12
    # +Y up at rest: the Y gyro senses the vertical component, X and Z the horizontal
    body = body_rate_dps(Mounting(1, 1.0), np.array([0.0]), np.array([0.0]), 50.46)[0] * 3600
    assert body[1] == pytest.approx(11.6003, abs=1e-3)
    assert np.hypot(body[0], body[2]) == pytest.approx(9.5754, abs=1e-3)
