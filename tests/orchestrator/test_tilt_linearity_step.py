"""The tilt_linearity step kind: the table (axis horizontal) in position mode as the indexing
head, the STIM300's inclinometers (datagram 0xA7) read at the vendor notes' angle points.

Real drivers against the simulators (stations/sim-tilt.yaml: inclinometer x channel
1.002·a + 0.002·a² + 0.001 g, y channel 0.01·a, white noise 5e-5 g per sample).
Hand-worked truths: for the 13 symmetric points ±90° in 15° steps the a² term is
orthogonal to the line, so the LS sensitivity is the scale 1.002, the residuals are
q·g²·(sin²θ − 7/13) (Σ sin² over the points = 7), the largest at θ = 0, and the
linearity is q·g·(7/13) / (2·1.002) · 100 % (span 2g·K); the lateral sensitivity is
0.01/1.002 = 0.998 %; the zero stability of 1-s means is 5e-5/√250/1.002 = 3.16e-6 g.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main
from tests.support.dry_run import dry_run, sim_procedure, station_file, write_procedure

REPO = Path(__file__).resolve().parents[2]
STATION = REPO / "stations" / "sim-tilt.yaml"

SEQUENCE = """\
sequence:
  - setpoint_c: 25.0
    tests: [{kind: tilt_linearity, points: vendor_90, dwell: 10 s, zero_stability: 2 min}]
"""


def _write(tmp: Path, station_text: str | None = None) -> Path:
    station = station_file(tmp, STATION, station_text)
    return write_procedure(tmp, sim_procedure("tilt (test)", "model: STIM300, serial: SIM-TILT",
                                              station, ["settle: 1 s"], SEQUENCE))


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("tilt")
    return dry_run(_write(tmp), tmp / "run")


@pytest.mark.timeout(180)
def test_the_dry_run_recovers_sensitivity_linearity_lateral_and_zero_stability(run: Path):
    (entry,) = json.loads((run / "report" / "results.json").read_text())["tilt_linearity"]
    assert entry["angles_deg"] == [float(a) for a in range(-90, 91, 15)]
    g = entry["gravity_g"]
    assert g == pytest.approx(1.000455, abs=1e-6)      # WGS-84 normal gravity at 50.46°, 0 m
    # noise on a 10-s point mean: 5e-5/√2500 = 1e-6 g, far inside these tolerances
    assert entry["sensitivity"] == pytest.approx(1.002, abs=2e-5)
    linearity = 0.002 * g * (7 / 13) / (2 * 1.002) * 100.0      # 0.05376 %
    assert entry["linearity_pct_fs"] == pytest.approx(linearity, rel=0.01)
    assert entry["residuals_g"][6] == pytest.approx(-0.002 * g * g * 7 / 13, abs=5e-6)
    assert entry["lateral_sensitivity_pct"] == pytest.approx(0.01 / 1.002 * 100.0, rel=0.01)
    zero = 5e-5 / math.sqrt(250) / 1.002
    assert entry["zero_stability_g"] == pytest.approx(zero, rel=0.2)   # 120 1-s means: ±13 %
    assert entry["zero_stability_over_s"] == 120.0


@pytest.mark.timeout(180)
def test_each_point_is_reached_in_position_mode_and_the_table_returns_to_rate_mode(run: Path):
    events = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
    reached = [(e["step_id"], e["angle_deg"]) for e in events if e["event"] == "table_position"]
    assert [a for _, a in reached] == [*[float(a) for a in range(-90, 91, 15)], 0.0]
    for event in (e for e in events if e["event"] == "table_position"):
        read = event["read_deg"]
        assert abs((read - event["angle_deg"] + 180.0) % 360.0 - 180.0) <= 0.001
    returned = [e for e in events if e["event"] == "returned_safe"][-1]
    assert returned["confirmed"]["table"] is True


def test_a_vertical_table_is_refused_naming_the_test(tmp_path, capsys):
    text = STATION.read_text().replace("  orientation: horizontal", "  orientation: vertical")
    assert main(["validate", str(_write(tmp_path, text))]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "p.yaml:16" in err and "table.orientation: horizontal" in err


def test_a_datagram_without_inclinometers_is_refused(tmp_path, capsys):
    text = STATION.read_text().replace("datagram: 0xA7", "datagram: 0x94")
    assert main(["validate", str(_write(tmp_path, text))]) == EXIT_BAD_INPUT
    assert "0x94 carries no inclinometers" in capsys.readouterr().err


@pytest.mark.timeout(180)
def test_an_interlock_opening_at_an_angle_point_is_a_fault_and_the_run_resumes(tmp_path):
    from gyrocal.cli import EXIT_FAULT

    out = tmp_path / "run"
    code = main(["run", str(_write(tmp_path)), "--sim", "--out", str(out),
                 "--inject", "table.interlock_open:always@T01.tilt.+30deg"])
    assert code == EXIT_FAULT
    events = [json.loads(x) for x in (out / "journal.jsonl").read_text().splitlines()]
    fault = [e for e in events if e["event"] == "fault"][-1]
    assert fault["step_id"] == "T01.tilt.+30deg"
    # the axis is horizontal: with the interlock open it cannot be held under servo, and
    # the safe state says so rather than calling an unpowered axis safe
    safe = [e for e in events if e["event"] == "safe_state"][-1]
    assert safe["confirmed"]["table"] is False and "interlock open" in safe["actions"]["table"]
    assert main(["resume", str(out)]) == EXIT_OK
    (entry,) = json.loads((out / "report" / "results.json").read_text())["tilt_linearity"]
    assert entry["sensitivity"] == pytest.approx(1.002, abs=2e-5)
