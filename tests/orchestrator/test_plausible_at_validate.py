"""Validate OK means run will start (issue 9, defect 5).

Reproducers from the adversarial pass: an acceleration or ramp of 1e-9 gave
an ETA of 327 million hours and validated; a 250 Hz procedure validated
against a 2000 Hz station that ``run`` then refused; neither flagship
procedure ran on ``stations/lab-example.yaml``. Each test here failed on main
before this change.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / "procedures" / "smoke.yaml"
LAB = REPO / "stations" / "lab-example.yaml"


def smoke_with(tmp_path: Path, *edits: tuple[str, str]) -> Path:
    text = SMOKE.read_text(encoding="utf-8").replace(
        "station: ../stations/sim.yaml", f"station: {REPO / 'stations' / 'sim.yaml'}")
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / "p.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def validate(capsys, *argv: str) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["validate", *argv])
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_an_acceleration_of_1e_9_is_refused_by_name(tmp_path: Path, capsys) -> None:
    path = smoke_with(tmp_path, ("  accel_dps2: 100.0", "  accel_dps2: 1.0e-9"))
    code, text = validate(capsys, str(path))
    assert code == EXIT_BAD_INPUT
    assert "defaults.accel_dps2: 1e-09 deg/s² is below the plausible minimum 0.01 deg/s²" in text
    assert "Traceback" not in text


def test_a_ramp_of_1e_9_is_refused_by_name(tmp_path: Path, capsys) -> None:
    path = smoke_with(tmp_path, ("  ramp_c_per_min: 5.0", "  ramp_c_per_min: 1.0e-9"))
    code, text = validate(capsys, str(path))
    assert code == EXIT_BAD_INPUT
    assert "defaults.ramp_c_per_min: 1e-09 °C/min is below the plausible minimum 0.01 °C/min" in text


def test_an_eta_over_14_days_needs_a_declared_max_duration(tmp_path: Path, capsys) -> None:
    # three 6-day Allan records: each duration is legal (≤ 7 days), the sum is 18+ days
    edits = [("sequence:\n", "sequence:\n" + "".join(
        f"  - setpoint_c: {t}\n    tests:\n      - {{kind: allan, duration: 6 d}}\n"
        for t in (24.0, 25.0, 26.0)))]
    code, text = validate(capsys, str(smoke_with(tmp_path, *edits)))
    assert code == EXIT_BAD_INPUT
    assert "the plan's ETA is 18." in text and "longer than 14 days" in text
    assert "unless it declares max_duration:" in text
    declared = smoke_with(tmp_path, *edits, ("\nname: ", "\nmax_duration: 20 d\nname: "))
    code, text = validate(capsys, str(declared))
    assert code == EXIT_OK, text
    short = smoke_with(tmp_path, *edits, ("\nname: ", "\nmax_duration: 15 d\nname: "))
    code, text = validate(capsys, str(short))
    assert code == EXIT_BAD_INPUT and "longer than its declared max_duration: 15 days" in text


def test_validate_applies_runs_sample_rate_rule(tmp_path: Path, capsys) -> None:
    """The reproducer: a 250 Hz procedure against a 2000 Hz station - validate refuses, as run does."""
    station = tmp_path / "lab-2000.yaml"
    station.write_text(LAB.read_text(encoding="utf-8").replace(
        "  sample_rate_hz: 250 ", "  sample_rate_hz: 2000 "), encoding="utf-8")
    procedure = REPO / "procedures" / "imu-calibration-5-temps.yaml"
    expected = (f"{procedure}: defaults.sample_rate_hz: 250 Hz, but the gyro of station "
                f"{station} is configured for 2000 Hz (gyro.sample_rate_hz)")
    code, text = validate(capsys, str(procedure), "--station", str(station))
    assert code == EXIT_BAD_INPUT and expected in text, text
    capsys.readouterr()
    run_code = main(["run", str(procedure), "--station", str(station),
                     "--out", str(tmp_path / "r")])
    assert run_code == EXIT_BAD_INPUT
    assert expected in capsys.readouterr().err


@pytest.mark.parametrize("name", ["fog-overnight-sf-temperature.yaml",
                                  "imu-calibration-5-temps.yaml"])
def test_the_flagship_procedures_validate_on_the_lab_example(name: str, capsys) -> None:
    code, text = validate(capsys, str(REPO / "procedures" / name), "--station", str(LAB))
    assert code == EXIT_OK, text
    assert ": OK — " in text and "Lab 2, bay 3" in text


def test_a_simulated_station_is_judged_as_for_run_sim(capsys) -> None:
    code, text = validate(capsys, str(REPO / "procedures" / "fog-overnight-sf-temperature.yaml"))
    assert code == EXIT_OK, text
    assert "OK for `gyrocal run --sim`" in text
