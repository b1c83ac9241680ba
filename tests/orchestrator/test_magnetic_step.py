"""The magnetic step kind: a dry run drives the coil through the simulated supply and recovers
the simulated gyro's magnetic sensitivity; bad coil sections are refused by name; a fault leaves
the coil off.

Real drivers against the simulators on loopback: the E36300 driver on channels 2 (+B) and 3
(-B) of the simulated supply, which the simulated gyro sees as a field of coil constant ×
(I₂ − I₃) along its input axis (stations/sim-magnetic.yaml: 5e-4 T/A, 1 % standard
uncertainty; gyro-models/fog-magnetic.yaml: 1e4 deg/(h·T), the vendor notes' unshielded FOG).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main
from tests.orchestrator.conftest import events
from tests.support.dry_run import dry_run, sim_procedure, station_file, write_procedure

REPO = Path(__file__).resolve().parents[2]
STATION = REPO / "stations" / "sim-magnetic.yaml"
TRUE_DPH_PER_T = 10000.0     # gyro-models/fog-magnetic.yaml
COIL_T_PER_A = 5e-4          # stations/sim-magnetic.yaml

SEQUENCE = """\
sequence:
  - setpoint_c: 25.0
    tests: [{{kind: magnetic, field_t: {field}, duration: 3 min}}]
"""


def _write(tmp: Path, field: str = "0.0005", station_text: str | None = None) -> Path:
    station = station_file(tmp, STATION, station_text)
    return write_procedure(tmp, sim_procedure("magnetic (test)", "model: FOG, serial: SIM-MAG",
                                              station, ["settle: 5 s"], SEQUENCE.format(field=field)))


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("mag")
    return dry_run(_write(tmp), tmp / "run")


@pytest.mark.timeout(120)
def test_the_dry_run_recovers_the_simulated_sensitivity_within_its_uncertainty(run: Path) -> None:
    (entry,) = json.loads((run / "report" / "results.json").read_text())["magnetic"]
    assert entry["steps"] == ["T01.mag.pos", "T01.mag.zero", "T01.mag.neg"]
    assert entry["field_t"] == pytest.approx([5e-4, 0.0, -5e-4], abs=1e-9)
    u = entry["uncertainty"]
    assert abs(entry["sensitivity_dph_per_t"] - TRUE_DPH_PER_T) <= u["U"]
    # the coil constant's 1 % is a type B line of the budget: 100 deg/(h·T) at 1e4
    coil = [c for c in u["budget"] if c["name"] == "coil constant"][0]
    assert coil["u_contribution"] == pytest.approx(0.01 * entry["sensitivity_dph_per_t"])
    # ±B of 0.5 mT at 1e4 deg/(h·T): ±5 deg/h about the zero-field bias
    assert entry["bias_dph"][0] - entry["bias_dph"][1] == pytest.approx(5.0, abs=0.5)
    assert entry["grade"].startswith("of the order of an unshielded FOG")


@pytest.mark.timeout(120)
def test_the_coil_is_set_read_back_and_switched_off_per_step(run: Path) -> None:
    coil = [e for e in events(run) if e["event"] == "coil_field"]
    sets = [(e["step_id"], e["set_field_t"], e["positive_current_a"], e["negative_current_a"])
            for e in coil if e["when"] == "set"]
    # 0.5 mT / 5e-4 T/A = 1 A on the +B channel, then both off, then 1 A on the -B channel
    assert sets == [("T01.mag.pos", 5e-4, 1.0, 0.0), ("T01.mag.zero", 0.0, 0.0, 0.0),
                    ("T01.mag.neg", -5e-4, 0.0, 1.0)]
    offs = [e for e in coil if e["when"] == "off"]
    assert len(offs) == 3 and all(e["field_t"] == 0.0 for e in offs)
    returned = [e for e in events(run) if e["event"] == "returned_safe"][-1]
    assert returned["confirmed"]["coil"] is True


def test_a_field_beyond_the_coil_is_refused_naming_the_line(tmp_path, capsys) -> None:
    procedure = _write(tmp_path, field="0.002")
    assert main(["validate", str(procedure)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "p.yaml:16" in err and "field_t" in err and "0.0005 T" in err


def test_a_coil_on_the_unit_power_channel_is_refused_naming_the_key(tmp_path, capsys) -> None:
    text = STATION.read_text().replace("positive_channel: 2", "positive_channel: 1")
    procedure = _write(tmp_path, station_text=text)
    line = text.splitlines().index(next(x for x in text.splitlines()
                                        if x.startswith("  positive_channel: 1"))) + 1
    assert main(["validate", str(procedure)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert f"station.yaml:{line}" in err and "coil.positive_channel" in err
    assert "powers the unit under test" in err


def test_a_magnetic_test_without_a_coil_is_refused(tmp_path, capsys) -> None:
    text = STATION.read_text()
    start, end = text.index("\ncoil:"), text.index("\nsimulation:")
    procedure = _write(tmp_path, station_text=text[:start] + text[end:])
    assert main(["validate", str(procedure)]) == EXIT_BAD_INPUT
    assert "has no coil: section" in capsys.readouterr().err


@pytest.mark.timeout(120)
def test_a_supply_dropout_mid_field_is_a_fault_that_leaves_the_coil_off(tmp_path, capsys) -> None:
    text = STATION.read_text().replace("unit_power: keep_on", "unit_power: switch_off")
    out = tmp_path / "run"
    code = main(["run", str(_write(tmp_path, station_text=text)), "--sim", "--out", str(out),
                 "--inject", "supply.dropout:always@T01.mag.pos"])
    assert code == EXIT_FAULT
    safe = [e for e in events(out) if e["event"] == "safe_state"][-1]
    assert safe["confirmed"]["coil"] is True
    assert safe["actions"]["coil"] == "coil switched off (read back: both channels off)"
    assert main(["resume", str(out)]) == EXIT_OK
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["magnetic"][0]["steps"] == ["T01.mag.pos", "T01.mag.zero", "T01.mag.neg"]


def test_the_plan_says_each_dwell_s_field_and_each_tilt_point_s_angle():
    from gyrocal.orchestrator.plan import expand_plan, format_plan
    from gyrocal.orchestrator.procedure import load_procedure

    text = format_plan(expand_plan(load_procedure(REPO / "procedures" / "magnetic-sensitivity.yaml")))
    assert "coil +0.5 mT" in text and "coil -0.5 mT" in text and "coil +0 mT" in text
    tilt = format_plan(expand_plan(load_procedure(REPO / "procedures" / "tilt-linearity.yaml")))
    assert "T01.tilt1.+30deg" in tilt and "at +30° (position)" in tilt
    assert "T01.tilt2.zero" in tilt and "at +0° (position)" in tilt
