"""The shipped acceptance-series procedure, dry: each covered test recovers the simulated
gyro's hand-typed truth (gyro-models/series-fog.yaml) within its reported uncertainty."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_OK, main

pytestmark = pytest.mark.timeout(300)
REPO = Path(__file__).resolve().parents[2]
DEAD_ZONE_DPS = 0.025     # typed from gyro-models/series-fog.yaml, not read from it
SATURATION_DPS = {"positive": 320.0, "negative": 270.0}


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
    assert [a["decision"] for a in results["acceptance"]] == ["PASS"] * 5
    html = (out / "report" / "report.html").read_text()
    assert "<h2>Threshold and resolution (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "0.03 (in (0.02, 0.03])" in html
    assert "<h2>Input rate limits (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "300 (limit in [300, 350))" in html
