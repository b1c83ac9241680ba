"""The accelerometer triad of a version-2 model file, against values worked by hand."""

import numpy as np
import pytest

from gyrocal.models.gyro_model import ModelError
from gyrocal.models.imu_model import Mounting, load_any_model, parse_imu_model, specific_force_imu_g

_AXIS = {"scale_factor": 1.0}


def _model(acc):
    return parse_imu_model({"version": 2, "reference_temp_c": 20.0,
                            "axes": {"x": _AXIS, "y": _AXIS, "z": _AXIS}, "accelerometers": acc},
                           "m.yaml")


def test_sensitivity_bias_and_misalignment_at_a_temperature():
    model = _model({"axes": {"x": {"bias_mg": 2.0, "bias_tempco_mg_per_c": 0.1,
                                   "sf_error_ppm": 100.0, "sf_tempco_ppm_per_c": 10.0},
                             "y": {}, "z": {"bias_mg": -1.0}},
                    "misalignment_urad": {"xy": 500.0},
                    "misalignment_tempco_urad_per_c": {"xy": 10.0}})
    acc = model.accelerometers
    # at 30 °C: bias x = 2 + 0.1*10 = 3 mg; SF x = 1 + (100 + 100) ppm; M_xy = 600 µrad
    assert acc.bias_g(30.0) == pytest.approx([3e-3, 0.0, -1e-3])
    k = acc.sensitivity(30.0)
    assert k[0, 0] == pytest.approx(1.0002)
    assert k[0, 1] == pytest.approx(1.0002 * 600e-6)
    assert k[1, 1] == 1.0 and k[2, 2] == 1.0
    out = acc.indicate(np.array([[0.0, 1.0, 0.0]]), 30.0, 100.0, np.random.default_rng(0))
    # x reads M_xy·SF_x·1 g + bias: 600.12 µg + 3 mg
    assert out[0, 0] == pytest.approx(1.0002 * 600e-6 + 3e-3, abs=1e-12)


def test_noise_is_the_velocity_random_walk():
    model = _model({"axes": {"x": {"vrw_mps_per_rth": 0.06}, "y": {}, "z": {}}})
    # 0.06 m/s/√h = 1e-3 m/s²·√s; at 400 Hz σ = 1e-3·20 m/s² = 0.02 m/s² = 2.0394e-3 g
    assert model.accelerometers.noise_sigma_g(400.0)[0] == pytest.approx(0.02 / 9.80665)


def test_down_mounting_reads_minus_gravity_on_its_axis():
    assert specific_force_imu_g(Mounting.parse("-y"), 1.0004) == pytest.approx([0.0, -1.0004, 0.0])


def test_the_shipped_imu_declares_its_accelerometers():
    acc = load_any_model("gyro-models/fog-imu.yaml").accelerometers
    assert acc.bias_mg == pytest.approx([2.0, -1.5, 0.8])
    assert acc.misalignment_urad[1, 2] == 500.0


@pytest.mark.parametrize(("acc", "message"), [
    ({"axes": {"x": {}, "y": {}}}, "accelerometers.axes.z: missing axis"),
    ({"axes": {"x": {"bias_ug": 1}, "y": {}, "z": {}}}, "accelerometers.axes.x.bias_ug: unknown key"),
    ({"axes": {"x": {}, "y": {}, "z": {}}, "misalignment_urad": {"xx": 1}}, "unknown element"),
    ({"axes": {"x": {"vrw_mps_per_rth": -1}, "y": {}, "z": {}}}, "must be >= 0"),
])
def test_bad_sections_name_the_key(acc, message):
    with pytest.raises(ModelError, match=message.replace(".", r"\.")):
        _model(acc)
