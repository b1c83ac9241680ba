"""Multi-axis IMU calibration: mountings in the procedure, remounts in the run, the matrix.

The dry runs go through the real drivers and simulators (Modbus chamber,
SCPI table, STIM300 datagrams on a pty); the simulated IMU is the version-2
model file, and the recovered matrix is compared with that model's truth,
computed from the file's numbers at the measured temperature.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main
from gyrocal.models.imu_model import Mounting as M
from gyrocal.models.imu_model import load_any_model
from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.orchestrator.remount import CONFIRM_FILE, FileConfirmOperator, check_mounting
from tests.orchestrator.conftest import events
from tests.support.dry_run import dry_run, sim_procedure

REPO = Path(__file__).resolve().parents[2]
STATION = REPO / "stations" / "sim-imu.yaml"
MODEL = load_any_model(REPO / "gyro-models" / "fog-imu.yaml")

PROCEDURE = sim_procedure(
    "short IMU calibration (test)", "model: FOG IMU, serial: IMU-SIM-01", STATION,
    ["dwell: 10 s", "settle: 2 s", "accel_dps2: 50.0"], """\
mountings:
  - {name: X, up: +x, face: A}
  - {name: Y, up: +y, face: B}
  - {name: Z, up: +z, face: C}
mounting_order: ORDER
sequence:
  - setpoint_c: 0.0
    tests: [{kind: sf_sweep, rates_dps: [50, 200], directions: both, min_revolutions: 2}]
  - setpoint_c: 40.0
    tests: [{kind: sf_sweep, rates_dps: [50, 200], directions: both, min_revolutions: 2}]
""")


def write(tmp_path: Path, order: str = "mountings_inside", edit: tuple[str, str] | None = None) -> Path:
    text = PROCEDURE.replace("ORDER", order)
    if edit is not None:
        assert edit[0] in text
        text = text.replace(edit[0], edit[1])
    path = tmp_path / "imu.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def imu_run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("imu")
    out = dry_run(write(tmp), tmp / "run", "--seed", "3")
    return out


def test_plan_ids_follow_the_mounting_order(tmp_path: Path) -> None:
    inside = expand_plan(load_procedure(write(tmp_path, "mountings_inside")))
    ids = [s.step_id for s in inside.steps]
    assert ids[:4] == ["T01.ramp", "T01.soak", "T01.MX.remount", "T01.MX.sf.+50dps"]
    assert ids.count("T01.ramp") == 1 and len([i for i in ids if i.endswith(".remount")]) == 6
    outside = expand_plan(load_procedure(write(tmp_path, "temperatures_inside")))
    ids = [s.step_id for s in outside.steps]
    assert ids[:4] == ["MX.remount", "MX.T01.ramp", "MX.T01.soak", "MX.T01.sf.+50dps"]
    assert [i for i in ids if i.endswith("remount")] == ["MX.remount", "MY.remount", "MZ.remount"]
    remount = outside.steps[0]
    assert remount.kind == "remount" and remount.mounting == "X"
    assert remount.label == "mount X (face A: IMU +X up along the table axis)"


@pytest.mark.parametrize(("edit", "message"), [
    (("up: +y, face: B", "up: +w, face: B"), r"imu\.yaml:\d+: mountings\[1\]\.up: must be an IMU axis"),
    (("name: Z, up: +z", "name: X, up: +z"), r"mountings\[2\]\.name: name 'X' is used twice"),
    (("name: Z, up: +z", "name: Z, up: -y"), r"mountings: the three-axis matrix needs every IMU "
                                             r"axis up once; no mounting has z up"),
    (("mounting_order: mountings_inside", "mounting_order: sideways"), r"mounting_order"),
])
def test_bad_mountings_are_bad_input_naming_the_line(tmp_path: Path, capsys, edit, message) -> None:
    assert main(["validate", str(write(tmp_path, edit=edit))]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert __import__("re").search(message, err), err


def test_dry_run_recovers_every_scale_factor_and_misalignment(imu_run: Path) -> None:
    results = json.loads((imu_run / "report" / "results.json").read_text())
    temps = results["imu"]["temperatures"]
    assert [t["setpoint_c"] for t in temps] == [0.0, 40.0]
    for t in temps:
        temp_c = t["temp_c"]
        sf_truth = MODEL.scale_factor(temp_c)
        e_truth = MODEL.misalignment_rad(temp_c) * 1e6
        for i, axis in enumerate("xyz"):
            assert abs(t["scale_factor"][axis] / sf_truth[i] - 1) * 1e6 < 20.0, (axis, t)
            for j, other in enumerate("xyz"):
                if i != j:
                    assert abs(t["misalignment_urad"][axis + other] - e_truth[i, j]) < 20.0
        # the bias (Earth rate removed) is the model's within its bias instability
        np.testing.assert_allclose([t["bias_dph"][a] for a in "xyz"], MODEL.bias_dph(temp_c),
                                   atol=0.3)
    check = results["imu"]["check"]
    assert all(max(row["in_sample"]["rms_dph"].values()) < 1.0 for row in check)
    # the single-axis sections are those of the unit-under-test axis (x) in its own mounting
    assert results["scale_factor"][0]["sf"] == pytest.approx(temps[0]["scale_factor"]["x"],
                                                             abs=2e-6)


def test_every_remount_is_asked_confirmed_and_checked(imu_run: Path) -> None:
    log = events(imu_run)
    asked = [e for e in log if e["event"] == "operator_needed"]
    assert [e["mounting"] for e in asked] == ["X", "Y", "Z", "X", "Y", "Z"]
    assert all(abs(e["table_rate_dps"]) < 0.05 for e in asked)       # table stopped first
    done = [e for e in log if e["event"] == "step_completed" and e["step_id"].endswith("remount")]
    assert [e["sensed_up"] for e in done] == ["+X", "+Y", "+Z"] * 2
    assert min(e["alignment"] for e in done) > 0.999


def test_a_wrong_remount_faults_clearly_and_resume_redoes_it(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(write(tmp_path)), "--sim", "--out", str(out), "--seed", "3",
                 "--inject", "fixture.wrong_mount@T01.MY.remount"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "step T01.MY.remount: mount check failed: declared IMU +Y up" in err
    assert "sensed on +Z" in err
    log = events(out)
    assert not any(e["event"] == "chunk_written" and ".MY." in e.get("path", "") for e in log)
    assert main(["resume", str(out)]) == EXIT_OK
    log = events(out)
    checked = [e for e in log if e["event"] == "step_completed" and e["step_id"] == "T01.MY.remount"]
    assert len(checked) == 1 and checked[0]["sensed_up"] == "+Y"
    assert json.loads((out / "report" / "results.json").read_text())["imu"]["temperatures"]


def test_the_mount_check_judges_the_direction_of_the_sensed_rate() -> None:
    rate = np.array([[0.001, -10.002, 0.003]] * 10)
    assert check_mounting(rate, M(1, -1.0), -10.0 * -1)["sensed_up"] == "-Y"
    with pytest.raises(Exception, match=r"declared IMU \+Y up.*sensed on -Y"):
        check_mounting(rate, M(1, 1.0), 10.0)


def test_operator_confirmation_file(tmp_path: Path, capsys) -> None:
    operator = FileConfirmOperator(tmp_path)
    assert not operator.confirmed("Y")
    (tmp_path / CONFIRM_FILE).write_text("X\n")          # a confirmation for another mounting
    assert not operator.confirmed("Y")
    assert main(["confirm", str(tmp_path), "--mounting", "Y"]) == EXIT_BAD_INPUT   # no run here
    (tmp_path / "journal.jsonl").write_text("")
    assert main(["confirm", str(tmp_path), "--mounting", "Y"]) == EXIT_OK
    assert operator.confirmed("Y")
    assert not (tmp_path / CONFIRM_FILE).exists()      # used once
