"""Model files: every contract violation is an error naming file, line and key path."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gyrocal.models.effects import EFFECTS
from gyrocal.models.gyro_model import (
    EffectSpec,
    GyroModel,
    ModelError,
    NoiseParams,
    dump_model,
    load_model,
    model_to_dict,
    parse_model,
)

pytestmark = pytest.mark.timeout(60)

REPO = Path(__file__).resolve().parents[2]
# single-axis (version 1) examples; the three-axis IMU file is tested in test_imu_model.py
EXAMPLES = sorted(p for p in (REPO / "gyro-models").glob("*.yaml")
                  if "\nversion: 2\n" not in "\n" + p.read_text())


def write(tmp_path: Path, text: str, name: str = "x.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def load_error(tmp_path: Path, text: str) -> str:
    path = write(tmp_path, text)
    with pytest.raises(ModelError) as info:
        load_model(path)
    return str(info.value)


def test_minimal_file_defaults_every_other_key_to_zero(tmp_path):
    model = load_model(write(tmp_path, "version: 1\nscale_factor: 2.5\n"))
    assert model == GyroModel(version=1, scale_factor=2.5)
    assert model.bias_dph == 0.0 and model.reference_temp_c == 0.0
    assert model.noise == NoiseParams() and model.effects == ()


def test_spec_example_loads_with_its_values():
    model = load_model(REPO / "gyro-models" / "nominal-fog.yaml")
    assert model.name == "nominal FOG"
    assert model.bias_tempco_dph_per_c == 0.03 and model.earth_rate_dph == 11.6
    assert model.noise.arw_deg_per_rth == 0.01 and model.noise.bias_instability_dph == 0.03
    assert model.effects == (EffectSpec("thermal_lag", {"tau_s": 600.0}),)


def test_out_of_range_effect_parameter_names_file_line_and_path(tmp_path):
    message = load_error(
        tmp_path,
        """
        version: 1
        scale_factor: 1.0
        effects:
          - name: bias_ramp
            dph_per_h: 0.1
          - name: warmup_transient
            amplitude_dph: 3.0
            tau_s: -5
        """,
    )
    path = tmp_path / "x.yaml"
    assert message == f"{path}:8: effects[1].tau_s: must be > 0, got -5"


def test_unknown_top_level_key(tmp_path):
    message = load_error(tmp_path, "version: 1\nscale_factor: 1\nbias_dps: 3\n")
    assert message.startswith(f"{tmp_path / 'x.yaml'}:3: bias_dps: unknown key")
    assert "bias_dph" in message  # the known keys are listed


def test_unknown_effect_name_lists_the_catalogue(tmp_path):
    message = load_error(
        tmp_path, "version: 1\nscale_factor: 1\neffects:\n  - name: thermal_drift\n    tau_s: 3\n"
    )
    assert ":4: effects[0].name: unknown effect 'thermal_drift'" in message
    for name in EFFECTS:
        assert name in message


def test_missing_effect_parameter(tmp_path):
    message = load_error(
        tmp_path, "version: 1\nscale_factor: 1\neffects:\n  - name: warmup_transient\n    tau_s: 30\n"
    )
    assert ":4: effects[0].amplitude_dph: missing parameter of effect 'warmup_transient'" in message


def test_unknown_effect_parameter(tmp_path):
    message = load_error(
        tmp_path,
        "version: 1\nscale_factor: 1\neffects:\n  - name: thermal_lag\n    tau_s: 30\n    tau_min: 1\n",
    )
    assert ":6: effects[0].tau_min: unknown key" in message


def test_same_effect_twice(tmp_path):
    message = load_error(
        tmp_path,
        """
        version: 1
        scale_factor: 1
        effects:
          - name: bias_ramp
            dph_per_h: 1
          - name: bias_ramp
            dph_per_h: 2
        """,
    )
    assert ":6: effects[1].name: effect 'bias_ramp' given twice (also effects[0])" in message


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("bias_dph: fast", "bias_dph: must be a number, got str 'fast'"),
        ("bias_dph: true", "bias_dph: must be a number, got bool True"),
        ("bias_dph: .nan", "bias_dph: must be a finite number, got nan"),
        ("earth_rate_dph: -.inf", "earth_rate_dph: must be a finite number, got -inf"),
        ("output_units: furlongs", "output_units: must be one of deg/s, deg/h, rad/s, V, LSB"),
        ("name: [1, 2]", "name: must be a string, got list"),
        ("effects: {name: thermal_lag}", "effects: must be a list, got dict"),
    ],
)
def test_wrong_type_or_non_finite_value(tmp_path, line, expected):
    message = load_error(tmp_path, f"version: 1\nscale_factor: 1\n{line}\n")
    assert f"x.yaml:3: {expected}" in message


def test_noise_keys_are_checked(tmp_path):
    message = load_error(tmp_path, "version: 1\nscale_factor: 1\nnoise:\n  arw: 0.1\n")
    assert ":4: noise.arw: unknown key" in message
    message = load_error(
        tmp_path, "version: 1\nscale_factor: 1\nnoise:\n  arw_deg_per_rth: 0.1\n  bias_instability_dph: -1\n"
    )
    assert ":5: noise.bias_instability_dph: must be >= 0, got -1" in message


def test_effect_parameter_type_and_finiteness(tmp_path):
    message = load_error(
        tmp_path, "version: 1\nscale_factor: 1\neffects:\n  - name: bias_ramp\n    dph_per_h: '0.1'\n"
    )
    assert ":5: effects[0].dph_per_h: must be a number, got str '0.1'" in message
    message = load_error(
        tmp_path, "version: 1\nscale_factor: 1\neffects:\n  - name: quantization\n    pulse_arcsec: .inf\n"
    )
    assert ":5: effects[0].pulse_arcsec: must be a finite number, got inf" in message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("scale_factor: 1\n", "version: required key is missing"),
        ("version: 1\n", "scale_factor: required key is missing"),
        ("version: 2\nscale_factor: 1\n", ":1: version: unsupported version 2"),
        ("version: 1.0\nscale_factor: 1\n", ":1: version: must be an integer, got 1.0"),
        ("version: 1\nscale_factor: 0\n", ":2: scale_factor: must be non-zero"),
        ("- 1\n- 2\n", "a model must be a mapping of keys, got a list of 2 entries"),
        ("", "empty model"),
    ],
)
def test_required_keys_and_version(tmp_path, text, expected):
    message = load_error(tmp_path, text)
    assert message.startswith(str(tmp_path / "x.yaml"))
    assert expected in message


def test_invalid_yaml_names_the_line(tmp_path):
    message = load_error(tmp_path, "version: 1\nscale_factor: 1\nnoise: {arw_deg_per_rth: 0.1\n")
    assert message.startswith(f"{tmp_path / 'x.yaml'}:")
    assert "malformed YAML" in message   # the one loader's spelling (gyrocal.inputs)


def test_missing_file_is_a_model_error(tmp_path):
    with pytest.raises(ModelError, match="cannot read model file"):
        load_model(tmp_path / "absent.yaml")


def test_parse_model_without_lines_still_names_source_and_path():
    with pytest.raises(ModelError) as info:
        parse_model(
            {"version": 1, "scale_factor": 1, "effects": [{"name": "dead_zone", "threshold_dps": 0}]},
            "workflow-output",
        )
    assert str(info.value) == "workflow-output: effects[0].threshold_dps: must be > 0, got 0"


def test_with_effect_validates_and_replaces():
    model = GyroModel(version=1, scale_factor=1.0)
    model = model.with_effect(EffectSpec("thermal_lag", {"tau_s": 100.0}))
    model = model.with_effect(EffectSpec("thermal_lag", {"tau_s": 200.0}))
    assert model.effects == (EffectSpec("thermal_lag", {"tau_s": 200.0}),)
    assert model.without_effect("thermal_lag").effects == ()
    with pytest.raises(ModelError, match=r"tau_s: must be > 0"):
        model.with_effect(EffectSpec("warmup_transient", {"amplitude_dph": 1.0, "tau_s": 0.0}))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_files_round_trip_through_dump(tmp_path, path):
    model = load_model(path)
    out = tmp_path / path.name
    dump_model(model, out)
    assert load_model(out) == model
    assert parse_model(model_to_dict(model)) == model


def test_example_files_cover_the_published_units():
    names = {p.name for p in EXAMPLES}
    assert {"nominal-fog.yaml", "kvg25.yaml", "kvg43.yaml", "vg951d.yaml", "rlg-dithered.yaml"} <= names
    kvg25 = load_model(REPO / "gyro-models" / "kvg25.yaml").noise
    assert (kvg25.quantization_arcsec, kvg25.arw_deg_per_rth, kvg25.bias_instability_dph) == (0.72, 0.003, 0.03)
    vg = load_model(REPO / "gyro-models" / "vg951d.yaml")
    markov = vg.effect("markov_bias")
    # sigma from M = 4.18 deg/h^1.5 and T_c = 528 s: sigma = M * sqrt(T_c[h] / 2)
    assert markov["sigma_dph"] == pytest.approx(4.18 * math.sqrt(528 / 3600 / 2), rel=1e-3)
    assert load_model(REPO / "gyro-models" / "rlg-dithered.yaml").has_effect("quantization")


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
positive = st.floats(min_value=1e-6, max_value=1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None)
@given(
    scale=positive,
    bias=finite,
    tempco=finite,
    arw=positive,
    tau=positive,
    phase=finite,
    name=st.text(max_size=20),
)
def test_any_valid_model_round_trips(tmp_path_factory, scale, bias, tempco, arw, tau, phase, name):
    model = GyroModel(
        version=1,
        scale_factor=scale,
        name=name,
        bias_dph=bias,
        bias_tempco_dph_per_c=tempco,
        noise=NoiseParams(arw_deg_per_rth=arw),
        effects=(
            EffectSpec("warmup_transient", {"amplitude_dph": bias, "tau_s": tau}),
            EffectSpec("table_angle_harmonic", {"amplitude_dph": tempco, "phase_deg": phase}),
        ),
    )
    out = tmp_path_factory.mktemp("rt") / "m.yaml"
    dump_model(model, out)
    assert load_model(out) == model


def test_every_problem_of_a_model_file_is_reported_in_one_pass(tmp_path):
    # read with the common schema reader: like a procedure, a model file lists all its
    # mistakes (in file order), so one edit round fixes them all
    message = load_error(
        tmp_path,
        """
        version: 1
        scale_factor: 0
        bias_dps: 3
        noise: {arw_deg_per_rth: -1}
        effects:
          - name: thermal_lag
            tau_s: -5
        """,
    )
    path = tmp_path / "x.yaml"
    assert message.splitlines() == [
        f"{path}:2: scale_factor: must be non-zero",
        f"{path}:3: bias_dps: unknown key 'bias_dps'; did you mean 'bias_dph'? (allowed here: "
        "bias_dph, bias_tempco_dph_per_c, earth_rate_dph, effects, name, noise, output_units, "
        "reference_temp_c, scale_factor, sf_error_ppm, sf_tempco_ppm_per_c, version)",
        f"{path}:4: noise.arw_deg_per_rth: must be >= 0, got -1",
        f"{path}:7: effects[0].tau_s: must be > 0, got -5",
    ]
