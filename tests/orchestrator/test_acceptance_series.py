"""The shipped acceptance-series procedure, dry: each covered test recovers the simulated
gyro's hand-typed truth (gyro-models/series-fog.yaml) within its reported uncertainty."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_OK, main

pytestmark = [pytest.mark.timeout(300), pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
DEAD_ZONE_DPS = 0.025     # typed from gyro-models/series-fog.yaml, not read from it
SATURATION_DPS = {"positive": 320.0, "negative": 270.0}
BANDWIDTH_HZ = 1.0        # rate_bandwidth, typed
PHASE_AT_HALF_HZ_DEG = -26.565051177   # −atan(0.5 / 1.0) in degrees, worked by hand
STARTUP_S = 0.8           # stations/sim-series.yaml simulation.gyro_startup_s, typed
WARMUP_TAU_S, WARMUP_DPH = 10.0, 20.0   # warmup_transient, typed
TIME_TO_BAND_S = 29.957322736          # 10 s · ln(20 / 1 deg/h), worked by hand
# simulation.turn_on_bias_dph 2.0 (1 σ per power-on), typed; each cycle's 10-s mean adds the
# white noise 0.6 deg/h/√Hz / √10 s = 0.19 deg/h: √(2² + 0.19²) = 2.009 deg/h
REPEATABILITY_DPH = 2.009


def test_the_acceptance_series_recovers_each_truth(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", str(REPO / "procedures" / "acceptance-series.yaml"), "--sim",
                 "--out", str(out), "--seed", "3"])
    assert code == EXIT_OK, capsys.readouterr()
    results = json.loads((out / "report" / "results.json").read_text())
    zero = next(t for t in results["threshold"]["tests"] if t["base_rate_dps"] == 0)
    assert zero["standard_test"] == "threshold (IEEE Std 952 / 1431)"
    assert zero["below_dps"] < DEAD_ZONE_DPS <= zero["threshold_dps"]
    assert abs(zero["estimate_dps"] - DEAD_ZONE_DPS) <= zero["U_dps"]
    assert results["threshold"]["resolution_dps"] == 0.01
    for walk in results["rate_limits"]["tests"]:
        truth = SATURATION_DPS[walk["direction"]]
        assert walk["max_dps"] <= truth < walk["next_dps"], walk
        assert abs(walk["estimate_dps"] - truth) <= walk["U_dps"]
        assert walk["next_dps"] - walk["max_dps"] == 50.0
    assert (results["rate_limits"]["max_positive_dps"],
            results["rate_limits"]["max_negative_dps"]) == (300.0, 250.0)
    response = results["frequency_response"]
    test = response["tests"][0]
    assert test["standard_test"] == "frequency response (IEEE Std 952 / 1431)"
    assert abs(response["bandwidth_hz"] - BANDWIDTH_HZ) <= test["U_bandwidth_hz"]
    assert 0 < test["U_bandwidth_hz"] < 0.01
    assert abs(response["phase_deg"] - PHASE_AT_HALF_HZ_DEG) <= test["U_phase_deg"]
    one_hz = next(p for p in test["points"] if p["freq_hz"] == 1.0)
    assert one_hz["gain_db"] == pytest.approx(-3.0103, abs=0.01)     # 1/√2 at the corner
    assert results["uncertainty"]["frequency_response.bandwidth_hz"]["U"] == \
        test["U_bandwidth_hz"]
    turn_on = results["turn_on"]["tests"][0]
    # the first frame is the first on the 250 Hz grid at or after output-on + 0.8 s: within
    # 4 ms of 0.8 s, inside U (0.02 s poll: U = 2·0.02/√12 = 0.0115 s)
    assert abs(turn_on["time_to_first_data_s"] - STARTUP_S) <= turn_on["U_time_to_first_data_s"]
    assert abs(turn_on["warmup_tau_s"] - WARMUP_TAU_S) <= turn_on["U_warmup_tau_s"], turn_on
    assert abs(turn_on["warmup_amplitude_dph"] - WARMUP_DPH) <= turn_on["U_warmup_amplitude_dph"]
    assert abs(turn_on["time_to_band_s"] - TIME_TO_BAND_S) <= turn_on["U_time_to_band_s"]
    assert turn_on["U_warmup_tau_s"] < 1.0
    assert results["uncertainty"]["turn_on.warmup_tau_s"]["U"] == turn_on["U_warmup_tau_s"]
    cycles = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()
              if '"unit_power_cycle"' in line]
    assert [c["step_id"] for c in cycles][0] == turn_on["step_id"]
    rep = results["turn_on_repeatability"]["tests"][0]
    assert rep["cycles"] == 8 and len(set(rep["biases_dph"])) == 8
    assert abs(rep["std_dph"] - REPEATABILITY_DPH) <= rep["U_std_dph"], rep
    assert rep["u_std_dph"] == pytest.approx(rep["std_dph"] / 14 ** 0.5)     # s/√(2(N−1))
    assert 0.5 < rep["in_run_std_dph"] < 0.8      # 1-s means of 0.6 deg/h/√Hz white noise
    assert [c["step_id"] for c in cycles][1:] == [f"T01.rep.c{n}" for n in range(1, 9)]
    assert [a["decision"] for a in results["acceptance"]] == ["PASS"] * 10
    html = (out / "report" / "report.html").read_text()
    assert "<h2>Threshold and resolution (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "0.03 (in (0.02, 0.03])" in html
    assert "<h2>Input rate limits (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "300 (limit in [300, 350))" in html
    assert "<h2>Frequency response (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "<h2>Turn-on time and warm-up (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "<h2>Turn-on-to-turn-on bias repeatability (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    synthesis = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()
                 if '"table_synthesis"' in line]
    assert [e["freq_hz"] for e in synthesis] == [0.25, 0.5, 0.75, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0]
    # TM-8004 §4.3.4: the oscillator takes the peak displacement, 1 deg/s / (2π · 0.25 Hz)
    assert synthesis[0]["displacement_deg"] == pytest.approx(0.636619772, abs=1e-9)
