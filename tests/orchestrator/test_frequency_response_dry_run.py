"""Frequency-response dry run: the simulated table turns the sinusoid in synthesis mode, the
simulated gyro sees it through its ``rate_bandwidth`` (models/effects.py), and the report's
−3 dB bandwidth and phase hold the hand-typed truth within U.

Truth, typed: a first-order response of 2 Hz, so the gain at 2 Hz is 1/√2 (−3.01 dB)
and the phase at 1 Hz is −atan(1/2) = −26.565°. A fault mid-sweep (the gyro stalls once
the table is sent into its third sinusoid) leaves the table stopped, read back, and the
resumed run turns that sinusoid again and finds the same bandwidth.
"""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from tests.orchestrator.conftest import SimCapture, events
from tests.orchestrator.test_threshold_dry_run import one_point_procedure, write_model_station

pytestmark = pytest.mark.timeout(300)
BANDWIDTH_HZ = 2.0
PHASE_AT_1HZ_DEG = -26.565051177

PROCEDURE = one_point_procedure("Frequency response check", "SIM-F", """\
      - kind: frequency_response
        amplitude_dps: 1.0
        frequencies_hz: [0.5, 1, 1.5, 1.8, 2, 2.2, 2.5, 3, 4]
        phase_at_hz: 1
        min_duration: 2 s
acceptance:
  - {name: Bandwidth, metric: frequency_response.bandwidth_hz, min: 1.5, unit: Hz,
     decision_rule: guarded}
""")


def write_inputs(tmp_path: Path) -> Path:
    write_model_station(tmp_path, f"[{{name: rate_bandwidth, bandwidth_hz: {BANDWIDTH_HZ}}}]")
    (tmp_path / "procedure.yaml").write_text(PROCEDURE, encoding="utf-8")
    return tmp_path / "procedure.yaml"


def check_truth(results: dict) -> dict:
    section = results["frequency_response"]
    test = section["tests"][0]
    assert abs(section["bandwidth_hz"] - BANDWIDTH_HZ) <= test["U_bandwidth_hz"], test
    assert abs(section["phase_deg"] - PHASE_AT_1HZ_DEG) <= test["U_phase_deg"], test
    for point in test["points"]:   # every gain within 4 u of 1/√(1 + (f/fc)²)
        truth = 1.0 / math.sqrt(1.0 + (point["freq_hz"] / BANDWIDTH_HZ) ** 2)
        assert abs(point["gain"] - truth) <= 4 * point["u_gain"] + 5e-4, point
    return test


def test_the_bandwidth_and_phase_are_recovered_within_u(tmp_path):
    out = tmp_path / "run"
    assert main(["run", str(write_inputs(tmp_path)), "--sim", "--out", str(out),
                 "--allow-outside-paths"]) == EXIT_OK
    results = json.loads((out / "report" / "results.json").read_text())
    test = check_truth(results)
    assert [p["freq_hz"] for p in test["points"]] == [0.5, 1, 1.5, 1.8, 2, 2.2, 2.5, 3, 4]
    assert results["acceptance"][0]["decision"] == "PASS"
    # the logged table rate is the commanded sinusoid: 1 deg/s peak
    steps = [e for e in events(out) if e["event"] == "table_synthesis"]
    assert [e["freq_hz"] for e in steps] == [0.5, 1, 1.5, 1.8, 2, 2.2, 2.5, 3, 4]
    assert {e["amplitude_dps"] for e in steps} == {1.0}


def test_without_a_bandwidth_the_gain_stays_at_one_and_no_bandwidth_is_claimed(tmp_path):
    procedure = write_inputs(tmp_path)
    write_model_station(tmp_path, "[]")
    text = procedure.read_text().split("acceptance:")[0]
    procedure.write_text(text, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out),
                 "--allow-outside-paths"]) == EXIT_OK
    results = json.loads((out / "report" / "results.json").read_text())
    section = results["frequency_response"]
    assert section["bandwidth_hz"] is None
    assert all(abs(p["gain"] - 1.0) < 2e-3 for p in section["tests"][0]["points"])
    assert any("never falls through −3 dB" in note for note in results["notes"])


def stall_on_third_sinusoid(sim) -> None:
    physics = sim.table_physics
    original = physics.set_mode_synthesis
    count = [0]
    fired = threading.Event()

    def spy(*args: float) -> None:
        original(*args)
        count[0] += 1
        if count[0] == 3 and not fired.is_set():
            fired.set()
            sim.gyro_faults.arm("stall", count=None)
    physics.set_mode_synthesis = spy


def test_a_sweep_faulted_mid_sinusoid_goes_safe_and_resumes_to_the_same_bandwidth(tmp_path):
    procedure = write_inputs(tmp_path)
    capture = SimCapture()
    capture.arm.append(stall_on_third_sinusoid)
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--allow-outside-paths"],
                on_sim_started=capture) == EXIT_FAULT
    assert capture.last.table_physics.mode == "off"          # synthesis ended by the safe state
    done = {e["step_id"] for e in events(out) if e["event"] == "step_completed"}
    assert "T01.freq.1Hz" in done and "T01.freq.1.5Hz" not in done
    capture.arm.clear()
    assert main(["resume", str(out)], on_sim_started=capture) == EXIT_OK
    synthesis = [e["step_id"] for e in events(out) if e["event"] == "table_synthesis"]
    assert synthesis.count("T01.freq.1.5Hz") == 2
    check_truth(json.loads((out / "report" / "results.json").read_text()))
