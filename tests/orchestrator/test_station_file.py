"""Station files: the shipped examples load; every mistake is named with file and line."""

import datetime as dt
import shutil
import textwrap
from pathlib import Path

import pytest

from gyrocal.orchestrator.station import load_station
from gyrocal.problems import ProcedureError

pytestmark = pytest.mark.timeout(30)

REPO = Path(__file__).resolve().parents[2]
SIM = REPO / "stations" / "sim.yaml"


def line_of(text, fragment):
    for number, line in enumerate(text.splitlines(), start=1):
        if fragment in line:
            return number
    raise AssertionError(fragment)


def station_problems(tmp_path, text):
    (tmp_path / "stations").mkdir(exist_ok=True)
    if not (tmp_path / "gyro-models").exists():
        shutil.copytree(REPO / "gyro-models", tmp_path / "gyro-models")
    path = tmp_path / "stations" / "station.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProcedureError) as error:
        load_station(path)
    return [str(p) for p in error.value.problems], path


def test_the_sim_station_loads_with_its_values():
    station = load_station(SIM)
    assert station.simulated
    assert station.site.latitude_deg == pytest.approx(50.46)
    assert station.chamber.driver == "watlow_f4"
    assert station.chamber.limits.max_ramp_c_per_min == 5.0
    assert station.chamber.safe_state.setpoint_c == 25.0
    assert station.chamber.identity.calibration_due == dt.date(2027, 6, 30)
    assert station.table.limits.max_rate_dps == 500.0
    assert station.gyro.rate_lsb == 2.0**-14
    assert station.simulation.chamber.max_cool_c_per_min == 3.0
    # the gyro model path is relative to the station file
    assert station.simulation.gyro_model == (REPO / "gyro-models" / "nominal-fog.yaml").resolve()


def test_the_lab_example_loads_and_is_not_simulated():
    station = load_station(REPO / "stations" / "lab-example.yaml")
    assert not station.simulated
    assert station.chamber.driver == "watlow_f4t"
    assert station.simulation is None
    assert station.chamber.identity.calibration_overdue(dt.date(2027, 1, 16))
    assert not station.chamber.identity.calibration_overdue(dt.date(2027, 1, 15))


def test_unknown_missing_and_wrong_values_are_all_reported_at_once(tmp_path):
    text = SIM.read_text(encoding="utf-8")
    text = text.replace("  unit_id: 1\n", "  unit_id: 1\n  baud: 9600\n")
    text = text.replace("  axis: 1\n", "  axis: one\n")
    text = text.replace("  rate_lsb: 6.103515625e-05          # output units per LSB (2**-14)\n", "")
    text = text.replace("latitude_deg: 50.46", "latitude_deg: 95")
    problems, path = station_problems(tmp_path, text)
    assert problems == [
        f"{path}:{line_of(text, 'latitude_deg')}: site.latitude_deg: 95 is above the maximum 90",
        f"{path}:{line_of(text, 'baud: 9600')}: chamber.baud: unknown key 'baud'; did you mean "
        "'baudrate'? (allowed here: address, baudrate, driver, identity, limit_input, limits, "
        "parity, retries, safe_state, stop_bits, timeout_s, unit_id, word_order)",
        f"{path}:{line_of(text, 'axis: one')}: table.axis: expected a whole number, got the text 'one'",
        f"{path}:{line_of(text, 'gyro:')}: gyro.rate_lsb: required key is missing",
    ]


def test_addresses_are_checked_per_driver(tmp_path):
    text = SIM.read_text(encoding="utf-8").replace(
        "  address: sim                       # started", "  address: 10.0.0.5:502  # started", 1)
    problems, path = station_problems(tmp_path, text)
    assert problems == [
        f"{path}:{line_of(text, '10.0.0.5:502')}: chamber.address: '10.0.0.5:502' is not an address "
        "for watlow_f4; expected a serial device (/dev/ttyUSB0, COM3) or socket://host:port or 'sim'"
    ]


def test_limits_must_make_sense_and_the_safe_state_must_be_inside_them(tmp_path):
    text = SIM.read_text(encoding="utf-8").replace(
        "limits: {min_temp_c: -70.0, max_temp_c: 150.0,", "limits: {min_temp_c: 30.0, max_temp_c: 20.0,")
    problems, path = station_problems(tmp_path, text)
    line = line_of(text, "min_temp_c: 30.0")
    safe = line_of(text, "safe_state:")
    assert problems == [
        f"{path}:{line}: chamber.limits.max_temp_c: max_temp_c 20 °C must be above min_temp_c 30 °C",
        f"{path}:{safe}: chamber.safe_state.setpoint_c: 25 °C is outside the chamber limits 30…20 °C",
    ]


def test_a_sim_address_needs_a_simulation_section(tmp_path):
    text = SIM.read_text(encoding="utf-8")
    text = text[: text.index("simulation:")]
    problems, path = station_problems(tmp_path, text)
    assert problems == [f"{path}:{line_of(text, 'version: 1')}: an instrument address is 'sim' "
                        "but there is no simulation section"]


def test_standby_safe_state_takes_no_setpoint(tmp_path):
    text = SIM.read_text(encoding="utf-8").replace(
        "safe_state: {action: setpoint, setpoint_c: 25.0}", "safe_state: {action: standby, setpoint_c: 25.0}")
    problems, path = station_problems(tmp_path, text)
    assert problems == [f"{path}:{line_of(text, 'standby')}: chamber.safe_state.setpoint_c: "
                        "setpoint_c applies only to action: setpoint"]


def test_a_station_that_is_not_a_mapping(tmp_path):
    problems, path = station_problems(tmp_path, textwrap.dedent("- a\n- b\n"))
    assert problems == [f"{path}:1: a station must be a mapping of keys, got a list of 2 entries"]


def test_a_missing_gyro_model_file_is_caught_before_the_run(tmp_path):
    text = SIM.read_text(encoding="utf-8").replace("nominal-fog.yaml", "nominal-fgo.yaml")
    problems, path = station_problems(tmp_path, text)
    missing = (tmp_path / "gyro-models" / "nominal-fgo.yaml").resolve()
    assert problems == [f"{path}:{line_of(text, 'gyro_model')}: simulation.gyro_model: gyro model "
                        f"file not found: {missing} (the path is relative to the file that names it)"]


def test_the_table_dialect_defaults_to_the_manuals_and_is_checked(tmp_path):
    """Issue 8/23: the reply dialect is a declared station property (only TM-8004's ACL over
    TCP remains), named on error with file:line; the lab example uses TM-9384C's port 9878."""
    assert load_station(SIM).table.dialect == "acl-tcp"
    lab = load_station(REPO / "stations" / "lab-example.yaml")
    assert lab.table.dialect == "acl-tcp" and lab.table.address.endswith("::9878::SOCKET")
    text = SIM.read_text(encoding="utf-8").replace("  axis: 1\n", "  axis: 1\n  dialect: scpi-error-queue\n")
    problems, path = station_problems(tmp_path, text)
    assert len(problems) == 1
    assert problems[0].startswith(f"{path}:{line_of(text, 'dialect: scpi-error-queue')}: table.dialect: ")
    assert "acl-tcp" in problems[0]
