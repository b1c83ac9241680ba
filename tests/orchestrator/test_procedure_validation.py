"""Procedure validation: every error class with its exact ``file:line: path: message`` shape."""

import shutil
from pathlib import Path

import pytest
import yaml

from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.problems import ProcedureError

pytestmark = pytest.mark.timeout(30)

REPO = Path(__file__).resolve().parents[2]

BASE = """\
version: 1
name: validation fixture
unit_under_test: {model: FOG, serial: 42, output_units: deg/s, nominal_scale_factor: 1.0}
station: ../stations/sim.yaml
safety:
  chamber: {min_temp_c: -40, max_temp_c: 80, max_ramp_c_per_min: 2.0}
  table: {max_rate_dps: 400, max_accel_dps2: 50}
defaults:
  ramp_c_per_min: 1.0
  soak: {tolerance_c: 0.5, hold: 10 min, max_wait: 1 h}
  dwell: 1 min
  settle: 10 s
  accel_dps2: 20
data_quality: {max_lost_frame_fraction: 0.001, max_step_repeats: 2}
sequence:
  - setpoint_c: 20
    tests:
      - {kind: static, duration: 5 min}
      - kind: sf_sweep
        rates_dps: [10, 100, 300]
  - setpoint_c: 40
    tests:
      - {kind: static, duration: 5 min}
      - {kind: sf_sweep, rates_dps: [10, 100, 300]}
      - {kind: allan, duration: 1 h}
acceptance:
  - {name: nonlinearity, metric: nonlinearity.rms_pct, max: 1.0, unit: "%"}
"""


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "stations").mkdir()
    shutil.copy(REPO / "stations" / "sim.yaml", tmp_path / "stations" / "sim.yaml")
    shutil.copytree(REPO / "gyro-models", tmp_path / "gyro-models")
    (tmp_path / "procedures").mkdir()
    return tmp_path


def line_of(text, fragment):
    for number, line in enumerate(text.splitlines(), start=1):
        if fragment in line:
            return number
    raise AssertionError(fragment)


def problems_for(folder, text, station=None):
    path = folder / "procedures" / "p.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProcedureError) as error:
        load_procedure(path, station)
    return [str(p) for p in error.value.problems], str(path)


def edit(old, new, text=BASE):
    assert old in text, old
    return text.replace(old, new, 1)


def test_the_fixture_itself_is_valid_and_expands(folder):
    path = folder / "procedures" / "p.yaml"
    path.write_text(BASE, encoding="utf-8")
    procedure = load_procedure(path)
    assert procedure.unit_under_test.serial == "42"
    assert [s.setpoint_c for s in procedure.sequence] == [20.0, 40.0]
    assert procedure.station.path == (folder / "stations" / "sim.yaml").resolve()
    assert procedure.files == (path.resolve(), (folder / "stations" / "sim.yaml").resolve())
    assert len(expand_plan(procedure).steps) == 2 * 2 + 2 * (1 + 6) + 1


def test_unknown_key_suggests_the_right_one(folder):
    text = edit("  dwell: 1 min\n", "  dwel: 1 min\n")
    problems, path = problems_for(folder, text)
    assert problems[0] == (
        f"{path}:{line_of(text, 'dwel:')}: defaults.dwel: unknown key 'dwel'; did you mean 'dwell'? "
        "(allowed here: accel_dps2, dwell, ramp_c_per_min, sample_rate_hz, settle, soak)"
    )
    # and, with no dwell default left, the sweeps that needed it say so
    assert len(problems) == 3 and all("no defaults.dwell" in p for p in problems[1:])


def test_wrong_type(folder):
    text = edit("max_step_repeats: 2", "max_step_repeats: many")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, 'many')}: data_quality.max_step_repeats: "
                        "expected a whole number, got the text 'many'"]


def test_missing_field_is_reported_where_its_parent_is(folder):
    text = edit("      - {kind: static, duration: 5 min}\n      - kind: sf_sweep",
                "      - {kind: static}\n      - kind: sf_sweep")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, '{kind: static}')}: sequence[0].tests[0].duration: "
                        "required key is missing"]


def test_missing_value_with_no_default_names_both_places(folder):
    text = edit("  dwell: 1 min\n", "")
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'kind: sf_sweep')}: sequence[0].tests[1].dwell: "
        "required key is missing (and there is no defaults.dwell)",
        f"{path}:{line_of(text, '{kind: sf_sweep')}: sequence[1].tests[1].dwell: "
        "required key is missing (and there is no defaults.dwell)",
    ]


def test_bad_duration_and_bad_unit(folder):
    text = edit("hold: 10 min", "hold: 10")
    text = edit("      - {kind: allan, duration: 1 h}", "      - {kind: allan, duration: 1 fortnight}", text)
    text = edit("rates_dps: [10, 100, 300]\n  - setpoint_c: 40", "rates_dps: [10, 1 km/h, 300]\n  - setpoint_c: 40", text)
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'hold: 10,')}: defaults.soak.hold: 10 is ambiguous: give a unit, "
        "e.g. '10 s', '10 min' or '10 h' (units: ms, s, sec, min, h, hr, d; bare numbers only in "
        "keys ending in _s)",
        f"{path}:{line_of(text, 'km/h')}: sequence[0].tests[1].rates_dps[1]: unknown unit 'km/h' in "
        "'1 km/h'; use one of deg/s, °/s, dps, deg/h, °/h, rad/s, rpm",
        f"{path}:{line_of(text, 'fortnight')}: sequence[1].tests[2].duration: unknown time unit "
        "'fortnight' in '1 fortnight'; use one of ms, s, sec, min, h, hr, d",
    ]


def test_setpoint_against_procedure_safety_and_station(folder):
    text = edit("  - setpoint_c: 40\n", "  - setpoint_c: 90\n")
    text = edit("min_temp_c: -40,", "min_temp_c: -80,", text)
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'min_temp_c: -80')}: safety.chamber.min_temp_c: -80 °C is below the "
        "station chamber limit -70 °C (../stations/sim.yaml: chamber.limits.min_temp_c)".replace(
            "../stations/sim.yaml", str(folder / "stations" / "sim.yaml")),
        f"{path}:{line_of(text, 'setpoint_c: 90')}: sequence[1].setpoint_c: 90 °C exceeds the chamber "
        "limit 80 °C (procedure safety.chamber.max_temp_c)",
    ]


def test_the_tighter_of_safety_and_station_limits_is_named(folder):
    station = folder / "stations" / "sim.yaml"
    # safety allows 400 deg/s, the station 500: 650 violates both, 400 is named
    text = edit("rates_dps: [10, 100, 300]\n  - setpoint_c", "rates_dps: [10, 650, 300]\n  - setpoint_c")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, '650')}: sequence[0].tests[1].rates_dps[1]: 650 deg/s "
                        "exceeds the table limit 400 deg/s (procedure safety.table.max_rate_dps)"]
    # when the procedure allows more than the station, the station's limit is named
    text = edit("max_rate_dps: 400", "max_rate_dps: 700", text)
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'max_rate_dps: 700')}: safety.table.max_rate_dps: 700 deg/s exceeds "
        f"the station table limit 500 deg/s ({station}: table.limits.max_rate_dps)",
        f"{path}:{line_of(text, '650')}: sequence[0].tests[1].rates_dps[1]: 650 deg/s exceeds the "
        f"table limit 500 deg/s (station {station}: table.limits.max_rate_dps)",
    ]


def test_ramp_and_acceleration_limits(folder):
    text = edit("  - setpoint_c: 40\n", "  - setpoint_c: 40\n    ramp_c_per_min: 3\n")
    text = edit("{kind: sf_sweep, rates_dps: [10, 100, 300]}",
                "{kind: sf_sweep, rates_dps: [10, 100, 300], accel_dps2: 60}", text)
    text = edit("  accel_dps2: 20\n", "  accel_dps2: 120\n", text)
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'accel_dps2: 120')}: defaults.accel_dps2: 120 deg/s² exceeds the "
        "table limit 50 deg/s² (procedure safety.table.max_accel_dps2)",
        f"{path}:{line_of(text, 'ramp_c_per_min: 3')}: sequence[1].ramp_c_per_min: 3 °C/min exceeds "
        "the chamber limit 2 °C/min (procedure safety.chamber.max_ramp_c_per_min)",
        f"{path}:{line_of(text, 'accel_dps2: 60')}: sequence[1].tests[1].accel_dps2: 60 deg/s² "
        "exceeds the table limit 50 deg/s² (procedure safety.table.max_accel_dps2)",
    ]


def test_station_override_applies_its_limits(folder):
    text = edit("max_rate_dps: 400", "max_rate_dps: 450")
    path = folder / "procedures" / "p.yaml"
    path.write_text(text, encoding="utf-8")
    assert load_procedure(path).station.name == "Simulated calibration station"   # 450 <= 500
    lab = folder / "lab-400.yaml"
    lab.write_text((REPO / "stations" / "lab-example.yaml").read_text().replace(
        "max_rate_dps: 500.0", "max_rate_dps: 400.0"))
    problems, shown = problems_for(folder, text, station=lab)
    assert problems == [
        f"{shown}:{line_of(text, 'max_rate_dps: 450')}: safety.table.max_rate_dps: 450 deg/s exceeds "
        f"the station table limit 400 deg/s ({lab}: table.limits.max_rate_dps)"
    ]


def test_bad_metric_name_unit_and_unmeasurable_metric(folder):
    text = edit("acceptance:\n", "acceptance:\n  - {name: typo, metric: allan.fit.B_dhp, max: 1}\n"
                "  - {name: units, metric: allan.fit.B_dph, max: 1, unit: ppm}\n"
                "  - {name: both, metric: asymmetry_ppm, max: 1, min: 0}\n")
    text = edit("      - {kind: allan, duration: 1 h}\n", "", text)
    problems, path = problems_for(folder, text)
    typo, units, both = (line_of(text, f"name: {n}") for n in ("typo", "units", "both"))
    assert problems[0].startswith(
        f"{path}:{typo}: acceptance[0].metric: unknown metric 'allan.fit.B_dhp'; did you mean "
        "allan.fit.B_dph? known metrics: nonlinearity.rms_pct, ")
    assert problems[1:] == [
        f"{path}:{units}: acceptance[1].unit: allan.fit.B_dph is in deg/h, not ppm",
        f"{path}:{units}: acceptance[1].metric: allan.fit.B_dph cannot be computed: it needs an "
        "allan test in the sequence",
        f"{path}:{both}: acceptance[2]: give exactly one of max or min",
    ]


def test_include_escaping_the_procedure_folder(folder):
    (folder / "shared.yaml").write_text("kind: static\nduration: 5 min\n", encoding="utf-8")
    text = edit("      - {kind: static, duration: 5 min}\n      - kind: sf_sweep",
                "      - !include ../shared.yaml\n      - kind: sf_sweep")
    problems, path = problems_for(folder, text)
    [problem] = problems
    assert problem.startswith(f"{path}:{line_of(text, '!include')}: sequence[0].tests[0]: "
                              "!include ../shared.yaml leaves the folder ")


def test_include_inside_the_folder_works_and_is_listed_for_the_manifest(folder):
    (folder / "procedures" / "static.yaml").write_text("kind: static\nduration: 7 min\n")
    text = edit("      - {kind: static, duration: 5 min}\n      - kind: sf_sweep",
                "      - !include static.yaml\n      - kind: sf_sweep")
    path = folder / "procedures" / "p.yaml"
    path.write_text(text, encoding="utf-8")
    procedure = load_procedure(path)
    assert procedure.sequence[0].tests[0].duration_s == 420.0
    assert (folder / "procedures" / "static.yaml").resolve() in procedure.files


def test_problems_inside_an_include_name_the_included_file(folder):
    inc = folder / "procedures" / "static.yaml"
    inc.write_text("kind: static\nduration: 7\n")
    text = edit("      - {kind: static, duration: 5 min}\n      - kind: sf_sweep",
                "      - !include static.yaml\n      - kind: sf_sweep")
    problems, _ = problems_for(folder, text)
    assert problems == [f"{folder / 'procedures' / 'static.yaml'}:2: sequence[0].tests[0].duration: "
                        "7 is ambiguous: give a unit, e.g. '7 s', '7 min' or '7 h' (units: ms, s, "
                        "sec, min, h, hr, d; bare numbers only in keys ending in _s)"]


def test_duplicate_key(folder):
    text = edit("  settle: 10 s\n", "  settle: 10 s\n  settle: 20 s\n")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, 'settle: 20 s')}: defaults.settle: duplicate key "
                        f"(first given on line {line_of(text, 'settle: 10 s')})"]


def test_malformed_yaml(folder):
    text = edit("  - setpoint_c: 40\n", "  - setpoint_c: 40\n   tests: [\n")
    problems, path = problems_for(folder, text)
    [problem] = problems
    assert problem.startswith(f"{path}:{line_of(text, 'tests: [')}: malformed YAML: ")


def test_station_problems_are_reported_with_the_station_file(folder):
    station = folder / "stations" / "sim.yaml"
    station.write_text(station.read_text().replace("max_accel_dps2: 100.0", "max_accel_dps2: fast"))
    problems, _ = problems_for(folder, BASE)
    line = line_of(station.read_text(), "max_accel_dps2: fast")
    assert problems == [
        f"{station}:{line}: table.limits.max_accel_dps2: 'fast' is not an angular acceleration; "
        "write a number with a unit, e.g. '10 deg/s²' (units: deg/s², deg/s^2, deg/s2, °/s², "
        "°/s^2, dps2, rad/s², rad/s^2)"
    ]


def test_missing_station_and_no_override(folder):
    text = edit("station: ../stations/sim.yaml\n", "")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:1: station: required key is missing (or give --station)"]


def test_schedule_and_rate_list_rules(folder):
    text = edit("rates_dps: [10, 100, 300]\n  - setpoint_c",
                "rates_dps: [10, 100, 300]\n        schedule: {spacing: log, start_dps: 1, "
                "stop_dps: 300, count: 5}\n  - setpoint_c")
    text = edit("{kind: sf_sweep, rates_dps: [10, 100, 300]}",
                "{kind: sf_sweep, schedule: {spacing: log, start_dps: 100, stop_dps: 10, count: 3}}",
                text)
    problems, path = problems_for(folder, text)
    assert problems == [
        f"{path}:{line_of(text, 'kind: sf_sweep')}: sequence[0].tests[1]: give either rates_dps "
        "(a list) or schedule (spacing, start_dps, stop_dps, count), not both",
        f"{path}:{line_of(text, 'start_dps: 100')}: sequence[1].tests[1].schedule.stop_dps: 10 deg/s "
        "is below start_dps 100 deg/s",
    ]


def test_soak_that_can_never_succeed(folder):
    text = edit("  - setpoint_c: 40\n", "  - setpoint_c: 40\n    soak: {hold: 2 h}\n")
    problems, path = problems_for(folder, text)
    assert problems == [f"{path}:{line_of(text, 'hold: 2 h')}: sequence[1].soak.max_wait: max_wait "
                        "(3600 s) is shorter than the hold time (7200 s): the soak could never succeed"]


def test_inline_station_mapping_is_validated_in_place(folder):
    station = yaml.safe_load((REPO / "stations" / "sim.yaml").read_text(encoding="utf-8"))
    station["table"]["limits"]["max_rate_dps"] = 200.0
    inline = yaml.safe_dump({"station": station}, sort_keys=False)
    text = edit("station: ../stations/sim.yaml\n", inline)
    problems, path = problems_for(folder, text)
    # the inline station is named by the procedure file and its own lines
    assert problems == [
        f"{path}:{line_of(text, 'max_rate_dps: 400')}: safety.table.max_rate_dps: 400 deg/s exceeds "
        f"the station table limit 200 deg/s ({path}: table.limits.max_rate_dps)",
        f"{path}:{line_of(text, 'rates_dps: [10, 100, 300]')}: sequence[0].tests[1].rates_dps[2]: "
        f"300 deg/s exceeds the table limit 200 deg/s (station {path}: table.limits.max_rate_dps)",
        f"{path}:{line_of(text, '{kind: sf_sweep, rates_dps')}: sequence[1].tests[1].rates_dps[2]: "
        f"300 deg/s exceeds the table limit 200 deg/s (station {path}: table.limits.max_rate_dps)",
    ]
    bad = edit("station: ../stations/sim.yaml\n", inline.replace("  seed: 1\n", "  seed: -1\n"))
    problems, path = problems_for(folder, bad)
    assert problems == [f"{path}:{line_of(bad, 'seed: -1')}: station.simulation.seed: "
                        "-1 is below the minimum 0"]


def test_plan_rates_are_exactly_what_the_table_demand_carries(tmp_path) -> None:
    """Issue 15: the plan's rate and the wire's rate are one definition (1e-6 deg/s fixed point)."""
    from gyrocal.instruments.table.acutrol_protocol import DEMAND_RATE
    from gyrocal.orchestrator.procedure import generate_rates

    for rate in generate_rates("log", 0.01, 0.09, 7) + generate_rates("linear", 1.0, 300.0, 11):
        wire = DEMAND_RATE.text(axis=1, rate_dps=rate).split(",")[1]
        assert float(wire) == rate, (rate, wire)


def test_a_limit_without_a_unit_is_in_its_metrics_unit(folder):
    """The report and the certificate print every value and limit with a unit: a limit given
    bare takes the metric's own, or the gyro's output units for SF-line metrics."""
    text = edit('  - {name: nonlinearity, metric: nonlinearity.rms_pct, max: 1.0, unit: "%"}\n',
                "  - {name: nonlinearity, metric: nonlinearity.rms_pct, max: 1.0}\n"
                "  - {name: SF, metric: scale_factor_ls.sf, min: 0.99}\n"
                "  - {name: ARW, metric: allan.fit.N_deg_per_rth, max: 0.01, unit: deg/sqrt(h)}\n")
    path = folder / "procedures" / "p.yaml"
    path.write_text(text, encoding="utf-8")
    units = {limit.name: limit.unit for limit in load_procedure(path).acceptance}
    assert units == {"nonlinearity": "%", "SF": "deg/s", "ARW": "deg/sqrt(h)"}
