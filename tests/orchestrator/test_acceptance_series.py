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


def test_the_acceptance_series_recovers_the_dead_zone(tmp_path, capsys):
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
    assert [a["decision"] for a in results["acceptance"]] == ["PASS"] * 3
    html = (out / "report" / "report.html").read_text()
    assert "<h2>Threshold and resolution (IEEE Std 952 / IEEE Std 1431)</h2>" in html
    assert "0.03 (in (0.02, 0.03])" in html
