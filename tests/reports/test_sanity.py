"""Physics before pass/fail: impossible numbers make a run INVALID, never PASS (issue 8)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_ACCEPTANCE_FAILED, main
from gyrocal.metrology.decision import Decision
from gyrocal.metrology.sanity import check_physics, verdict
from gyrocal.reports.acceptance import evaluate_acceptance
from tests.support.verdicts import judged


def results(sf: float = 1.0002, nonlinearity: float = 0.001, mean: float = 10.0,
            bias: float = 2.0) -> dict:
    return {"unit_under_test": {"nominal_scale_factor": 1.0},
            "scale_factor": [{"temp_c": 25.0, "sf": sf}],
            "nonlinearity": {"rms_pct": nonlinearity, "max_ppm_fs": abs(nonlinearity) * 1e4},
            "sf_temperature": None,
            "steps": [{"step_id": "T01.sf.+10dps", "kind": "dwell", "rate_dps": 10.0,
                       "output_mean": mean},
                      {"step_id": "T01.sf.+0.0001dps", "kind": "dwell", "rate_dps": 0.0001,
                       "output_mean": -0.0005}],        # a bias may flip a tiny rate: not checked
            "bias": [{"temp_c": 25.0, "bias_dph": bias}]}


def test_a_sound_run_passes_its_physics() -> None:
    checks = check_physics(results())
    assert all(c.ok for c in checks)
    assert verdict(checks, [judged(Decision.PASS)]).overall.value == "PASS"
    assert verdict(checks, [judged(Decision.FAIL)]).overall.value == "FAIL"


@pytest.mark.parametrize(("bad", "check"), [
    (dict(sf=1e-6), "scale factor near nominal"),          # the stale-frame report of issue 8
    (dict(sf=1.07), "scale factor near nominal"),
    (dict(sf=math.nan), "scale factor near nominal"),
    (dict(nonlinearity=-0.01), "non-negative spreads"),
    (dict(mean=-9.99), "dwell signs follow the table"),
    (dict(bias=math.inf), "bias finite"),
])
def test_impossible_numbers_are_invalid_whatever_the_limits_say(bad: dict, check: str) -> None:
    checks = check_physics(results(**bad))
    result = verdict(checks, [judged(Decision.PASS)]).to_json()
    assert result["overall"] == "INVALID"
    assert [c.name for c in checks if not c.ok] == [check]
    assert result["invalid_because"][0].startswith(check)


def test_the_tolerance_is_the_procedures() -> None:
    assert not check_physics(results(sf=1.07))[0].ok
    assert check_physics(results(sf=1.07), sf_tolerance_pct=10)[0].ok


def test_max_limits_fail_on_nan_and_impossible_negatives_and_bound_signed_sizes() -> None:
    notes: list[str] = []
    data = {"nonlinearity": {"rms_pct": -0.01}, "asymmetry_ppm": -300.0,
            "sf_temperature": {"instability_pct": math.nan}}
    limits = [{"name": "nl", "metric": "nonlinearity.rms_pct", "max": 0.05},
              {"name": "asym", "metric": "asymmetry_ppm", "max": 200.0},
              {"name": "inst", "metric": "sf_temperature.instability_pct", "max": 0.1}]
    assert [v.passed for v in evaluate_acceptance(data, limits, notes)] == [False, False, False]
    data["asymmetry_ppm"] = -50.0
    assert evaluate_acceptance(data, limits[1:2], notes)[0].passed is True


def test_an_impossible_run_folder_is_invalid_in_the_report_and_the_exit_code(
        tmp_path: Path, capsys) -> None:
    """The hand-made record of test_build_unit, its gyro output scaled by 1e-6."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from tests.support.hand_run import write_run

    run = write_run(tmp_path)
    for chunk in (run / "samples").rglob("*.parquet"):
        table = pq.read_table(chunk)
        gyro = table.column("gyro").to_numpy() * 1e-6
        pq.write_table(table.set_column(table.schema.get_field_index("gyro"), "gyro",
                                        pa.array(np.asarray(gyro))), chunk)
    assert main(["report", str(run)]) == EXIT_ACCEPTANCE_FAILED
    out = capsys.readouterr().out
    assert "INVALID" in out and "scale factor near nominal" in out
    saved = json.loads((run / "report" / "results.json").read_text())
    assert saved["verdict"]["overall"] == "INVALID"
    assert all(a["pass"] for a in saved["acceptance"])     # the limit alone would have passed
    html = (run / "report" / "report.html").read_text()
    assert 'class="invalid"' in html and "scale factor near nominal" in html


def with_drift(deviation: float, noise_limit: float = 1e-4, mean: float = 10.0) -> dict:
    base = results(mean=mean)
    base["steps"][0]["drift"] = {"deviation": deviation, "noise_limit": noise_limit,
                                 "segment": 0, "segments": 10}
    return base


def test_a_dwell_whose_first_tenth_strays_is_invalid() -> None:
    """Issue 28: 80 samples of the table's ramp (84 → 99.8 deg/s) at the start of a 2500-sample
    dwell at 100 deg/s put its first tenth 2.592 deg/s (26,000 ppm) below the rest."""
    checks = check_physics(with_drift(2.592, noise_limit=0.002, mean=99.9))
    result = verdict(checks, [judged(Decision.PASS)]).to_json()
    assert result["overall"] == "INVALID"
    assert [c.name for c in checks if not c.ok] == ["dwells steady"]
    assert "T01.sf.+10dps: part 1 of 10" in result["invalid_because"][0]


def test_slow_physics_within_the_floor_keeps_a_dwell_steady() -> None:
    # at 10 deg/s the floor is max(100 ppm × 10, 2 deg/h) = 0.001 deg/s, plus 0.0001 of noise
    assert all(c.ok for c in check_physics(with_drift(0.0009)))
    assert all(c.ok for c in check_physics(with_drift(0.0011)))
    assert not all(c.ok for c in check_physics(with_drift(0.00115)))
    # a tiny rate is not judged (its mean may be mostly bias)
    tiny = results()
    tiny["steps"][1]["drift"] = {"deviation": 1.0, "noise_limit": 0.0, "segment": 3, "segments": 10}
    assert all(c.ok for c in check_physics(tiny))
