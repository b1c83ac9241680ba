"""Verdicts at the edges (issue 28): nothing is graded that was not measured, nothing unidentifiable is 0.

Measured before: a report rebuilt on an interrupted run graded the ARW and
bias-instability limits on a 10-minute static because the 2-hour hold never
ran (B = 0, PASS); Q = 0 (not identifiable) graded PASS against a max limit;
a value within U of its limit printed a plain PASS with no U under the simple
rule.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gyrocal.analysis.allan.summary import allan_curve, fit_curve, identifiability_json
from gyrocal.app.verdict import verdict_line
from gyrocal.cli import EXIT_ACCEPTANCE_FAILED, EXIT_FAULT, main
from gyrocal.metrology.decision import Decision, overall_verdict
from gyrocal.reports.acceptance import evaluate_acceptance
from tests.orchestrator.conftest import write_station

pytestmark = pytest.mark.timeout(300)


def _procedure(folder: Path) -> Path:
    station = write_station(folder)
    path = folder / "procedure.yaml"
    path.write_text(f"""
version: 1
name: Interrupted before the long hold
unit_under_test: {{model: Simulated FOG, serial: SIM-V, output_units: deg/s, nominal_scale_factor: 1.0}}
station: {station}
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults:
  ramp_c_per_min: 5.0
  soak: {{tolerance_c: 0.5, hold: 10 s, max_wait: 10 min}}
  dwell: 8 s
  settle: 1 s
  accel_dps2: 100.0
  sample_rate_hz: 250
data_quality:
  max_lost_frame_fraction: 0.01
  max_step_repeats: 2
sequence:
  - setpoint_c: 23.0
    tests:
      - {{kind: static, duration: 10 min}}
      - {{kind: sf_sweep, rates_dps: [20]}}
      - {{kind: allan, duration: 2 h}}
acceptance:
  - {{name: Angle random walk N, metric: allan.fit.N_deg_per_rth, max: 0.25, unit: deg/√h}}
  - {{name: Bias instability B, metric: allan.fit.B_dph, max: 0.25, unit: deg/h}}
  - {{name: SF asymmetry, metric: asymmetry_ppm, max: 20000, unit: ppm}}
""")
    return path


def test_a_report_rebuilt_before_the_long_hold_ran_does_not_grade_the_noise_terms(
        tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(_procedure(tmp_path)), "--sim", "--seed", "5", "--out", str(out),
                 "--inject", "chamber.alarm:always@T01.allan"])
    assert code == EXIT_FAULT
    events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
    done = {e["step_id"] for e in events if e["event"] == "step_completed"}
    assert "T01.static" in done and "T01.allan" not in done     # the 10-min static, no 2-h hold
    capsys.readouterr()
    assert main(["report", str(out)]) == EXIT_ACCEPTANCE_FAILED
    printed = capsys.readouterr().out
    results = json.loads((out / "report" / "results.json").read_text())
    by_name = {a["name"]: a for a in results["acceptance"]}
    for name in ("Angle random walk N", "Bias instability B"):
        assert by_name[name]["decision"] == "NOT EVALUATED" and by_name[name]["value"] is None
        assert "allan test" in by_name[name]["why"]
        assert f"NOT EVALUATED  {name}: not measured" in printed
    assert results["allan"]["step_id"] == "T01.static"      # the fit exists, but is not graded
    assert by_name["SF asymmetry"]["decision"] == "PASS"      # the sweep did complete
    assert results["verdict"]["overall"] == "INCOMPLETE"
    assert results["verdict"]["not_evaluated"] == ["Angle random walk N", "Bias instability B"]
    html = (out / "report" / "report.html").read_text()
    assert "NOT EVALUATED" in html and "INCOMPLETE" in html


def _white_noise_fit() -> dict[str, Any]:
    """An Allan fit of pure white rate noise (N only): quantization and rate ramp are not in it."""
    rng = np.random.default_rng(7)
    fs_hz = 100.0
    rate_dph = rng.normal(0.0, 0.1 * 60.0 * np.sqrt(fs_hz), 200_000)   # N = 0.1 deg/√h
    fit = fit_curve(allan_curve(rate_dph, fs_hz))
    return {"fit": fit.to_json(), **identifiability_json(fit)}


def test_a_noise_term_the_record_cannot_identify_is_never_graded_as_zero() -> None:
    allan = _white_noise_fit()
    assert allan["identifiable"]["N_deg_per_rth"] is True
    assert allan["fit"]["N_deg_per_rth"] == pytest.approx(0.1, rel=0.05)
    assert allan["identifiable"]["Q_arcsec"] is False and allan["identifiable"]["R_dph_per_h"] is False
    bound_q = allan["upper_bound_95"]["Q_arcsec"]
    assert 0 < bound_q < np.inf
    results = {"allan": allan, "uncertainty": {}}
    limits = [{"name": "Q tight", "metric": "allan.fit.Q_arcsec", "max": bound_q / 2, "unit": "arcsec"},
              {"name": "Q loose", "metric": "allan.fit.Q_arcsec", "max": bound_q * 2, "unit": "arcsec"},
              {"name": "Q min", "metric": "allan.fit.Q_arcsec", "min": 0.01, "unit": "arcsec"}]
    notes: list[str] = []
    verdicts = {v.name: v for v in evaluate_acceptance(results, limits, notes)}
    assert verdicts["Q tight"].decision is Decision.NOT_EVALUATED     # was: Q = 0, PASS
    assert verdicts["Q loose"].decision is Decision.PASS             # the bound settles it
    assert verdicts["Q min"].decision is Decision.NOT_EVALUATED      # a bound cannot show ≥
    for verdict in verdicts.values():
        assert verdict.value is None and verdict.identifiable is False
        assert verdict_line(verdict).startswith("not identifiable from this record (95 % upper "
                                                f"bound {bound_q:.3g} arcsec)")
    assert overall_verdict([], list(verdicts.values()), []).overall.value == "INCOMPLETE"
    assert any("Q tight" in note and "not identifiable" in note for note in notes)


def test_every_verdict_line_prints_value_plus_minus_u_with_units() -> None:
    results = {"asymmetry_ppm": 95.0, "uncertainty": {"asymmetry_ppm": {"U": 12.0}},
               "nonlinearity": {"rms_pct": 0.5}}
    limits = [{"name": "asym", "metric": "asymmetry_ppm", "max": 100.0, "unit": "ppm"},
              {"name": "nl", "metric": "nonlinearity.rms_pct", "max": 1.0, "unit": "%"}]
    verdicts = evaluate_acceptance(results, limits, [])
    near = verdict_line(verdicts[0])       # 95 within U = 12 of 100, simple rule: PASS with U
    assert verdicts[0].decision is Decision.PASS
    assert near == "95 ± 12 ppm (max 100 ppm, simple rule)"
    assert verdict_line(verdicts[1]) == "0.5 (U not stated) % (max 1 %, simple rule)"
