"""Threshold dry run: the simulated gyro's dead zone (models/effects.py) is what the test finds.

A hand-typed truth: a dead zone of 0.025 deg/s reads every rate below it as 0, so
at zero rate the increments 0.01 and 0.02 deg/s give no output change and 0.03 deg/s
gives its full change; the reported threshold is 0.03 deg/s and its interval
(0.02, 0.03] holds the truth. At +10 deg/s the dead zone plays no part and the
smallest increment is resolved. Without the dead zone the smallest increment at zero
rate passes too, so it is the dead zone, not the table's at-rate band (0.05 deg/s,
wider than every increment here), that the test measures.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from tests.orchestrator.conftest import SimCapture, events, when_table_commanded

pytestmark = pytest.mark.timeout(300)
REPO = Path(__file__).resolve().parents[2]

MODEL = """version: 1
name: FOG with a dead zone
output_units: deg/s
scale_factor: 1.0
reference_temp_c: 25.0
bias_dph: 2.0
bias_tempco_dph_per_c: 0.0
sf_error_ppm: 0.0
sf_tempco_ppm_per_c: 0.0
earth_rate_dph: 11.6
noise: {arw_deg_per_rth: 0.01, bias_instability_dph: 0.03, rrw_deg_per_h_rth: 0.0,
        quantization_arcsec: 0.0, rate_ramp_dph_per_h: 0.0}
effects: EFFECTS
"""


def one_point_procedure(name: str, serial: str, rest: str) -> str:
    """A one-temperature (23 °C) procedure on station.yaml beside it; ``rest`` follows ``tests:``."""
    return f"""version: 1
name: {name}
unit_under_test: {{model: Simulated FOG, serial: {serial}, output_units: deg/s,
                  nominal_scale_factor: 1.0}}
station: station.yaml
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults: {{ramp_c_per_min: 5.0, soak: {{tolerance_c: 0.5, hold: 10 s, max_wait: 10 min}},
           dwell: 5 s, settle: 1 s, accel_dps2: 100.0, sample_rate_hz: 250}}
data_quality: {{max_lost_frame_fraction: 0.01, max_step_repeats: 2}}
sequence:
  - setpoint_c: 23.0
    tests:
{rest}"""


PROCEDURE = one_point_procedure("Threshold check", "SIM-T", """\
      - kind: threshold
        base_rates_dps: [0, 10]
        increments_dps: [0.01, 0.02, 0.03, 0.04]
acceptance:
  - {name: Threshold, metric: threshold.threshold_dps, max: 0.04, unit: deg/s,
     decision_rule: guarded}
""")


def write_model_station(tmp_path: Path, effects: str) -> None:
    """model.yaml (MODEL with ``effects``) and station.yaml (the sim station using it) in tmp_path."""
    tmp_path.mkdir(exist_ok=True)
    (tmp_path / "model.yaml").write_text(MODEL.replace("EFFECTS", effects), encoding="utf-8")
    station = (REPO / "stations" / "sim.yaml").read_text(encoding="utf-8")
    station = station.replace("../gyro-models/nominal-fog.yaml", str(tmp_path / "model.yaml"))
    (tmp_path / "station.yaml").write_text(station, encoding="utf-8")


def write_inputs(tmp_path: Path, effects: str, increments: str) -> Path:
    write_model_station(tmp_path, effects)
    (tmp_path / "procedure.yaml").write_text(
        PROCEDURE.replace("[0.01, 0.02, 0.03, 0.04]", increments), encoding="utf-8")
    return tmp_path / "procedure.yaml"


def run_threshold(tmp_path: Path, effects: str,
                  increments: str = "[0.01, 0.02, 0.03, 0.04]") -> dict:
    write_inputs(tmp_path, effects, increments)
    out = tmp_path / "run"
    code = main(["run", str(tmp_path / "procedure.yaml"), "--sim", "--out", str(out),
                 "--allow-outside-paths"])
    assert code == EXIT_OK
    return json.loads((out / "report" / "results.json").read_text())


def test_the_dead_zone_is_the_threshold_and_lies_in_its_interval(tmp_path):
    truth_dps = 0.025
    results = run_threshold(tmp_path, f"[{{name: dead_zone, threshold_dps: {truth_dps}}}]")
    section = results["threshold"]
    zero, ten = section["tests"]
    assert [i["passes"] for i in zero["increments"]] == [False, False, True, True]
    assert [abs(i["measured_dps"]) < 4 * i["u_dps"] for i in zero["increments"][:2]] == [True] * 2
    assert section["threshold_dps"] == 0.03 and zero["below_dps"] == 0.02
    assert zero["below_dps"] < truth_dps <= zero["threshold_dps"]
    assert abs(zero["estimate_dps"] - truth_dps) <= zero["U_dps"]
    assert section["resolution_dps"] == 0.01 and all(i["passes"] for i in ten["increments"])
    limit = results["acceptance"][0]
    # the guarded rule: 0.03 + U (0.0058) lies inside 0.04
    assert limit["value"] == 0.03 and limit["decision"] == "PASS"
    assert limit["guard_band"] == pytest.approx(2 * 0.01 / 12 ** 0.5)
    assert results["uncertainty"]["threshold.threshold_dps"]["U"] == pytest.approx(
        2 * 0.01 / 12 ** 0.5)


def test_without_the_dead_zone_the_smallest_increment_is_resolved(tmp_path):
    section = run_threshold(tmp_path, "[]")["threshold"]
    assert section["threshold_dps"] == 0.01 and section["resolution_dps"] == 0.01
    zero = section["tests"][0]
    assert all(i["passes"] for i in zero["increments"])
    assert all(abs(i["measured_dps"] / i["commanded_dps"] - 1) < 0.05 for i in zero["increments"])


def test_coarse_output_quantization_raises_the_threshold(tmp_path):
    """Pulse counting (``quantization``, 36 arcsec = 0.01 deg a pulse) at 250 Hz: each sample
    is a whole number of pulses, so a 5 s dwell's mean is uncertain by up to a pulse in 5 s
    (0.002 deg/s) instead of the white noise's ~6e-5 deg/s, and increments of 0.001 deg/s
    that the white noise alone resolves are no longer resolved."""
    increments = "[0.001, 0.002, 0.005, 0.01]"
    smooth = run_threshold(tmp_path / "smooth", "[]", increments)["threshold"]
    coarse = run_threshold(tmp_path / "coarse", "[{name: quantization, pulse_arcsec: 36}]",
                           increments)["threshold"]
    assert smooth["threshold_dps"] == 0.001
    assert coarse["threshold_dps"] > 0.001
    assert coarse["tests"][0]["increments"][0]["u_dps"] > \
        10 * smooth["tests"][0]["increments"][0]["u_dps"]


def test_a_threshold_run_faulted_mid_walk_resumes_and_finds_the_same_threshold(tmp_path):
    """The gyro stalls for good once the table is asked for +0.02 deg/s: the run goes safe
    (exit 3) before that increment completes. The resumed session commands the increment
    again although it lies inside the table's at-rate band of the stopped table's 0 deg/s."""
    procedure = write_inputs(tmp_path, "[{name: dead_zone, threshold_dps: 0.025}]",
                             "[0.01, 0.02, 0.03, 0.04]")
    capture = SimCapture()
    capture.arm.append(lambda sim: when_table_commanded(
        sim, 0.02, lambda: sim.gyro_faults.arm("stall", count=None)))
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--allow-outside-paths"],
                on_sim_started=capture) == EXIT_FAULT
    done = {e["step_id"] for e in events(out) if e["event"] == "step_completed"}
    assert "T01.thr.+0dps.+0.01dps" in done and "T01.thr.+0dps.+0.02dps" not in done
    capture.arm.clear()
    demands: list[float] = []

    def record_demands(sim) -> None:
        physics = sim.table_physics
        original = physics.set_rate_demand_dps

        def spy(value: float) -> None:
            demands.append(float(value))
            original(value)
        physics.set_rate_demand_dps = spy
    capture.arm.append(record_demands)
    assert main(["resume", str(out)], on_sim_started=capture) == EXIT_OK
    assert 0.02 in demands
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["threshold"]["threshold_dps"] == 0.03
    assert results["acceptance"][0]["decision"] == "PASS"
