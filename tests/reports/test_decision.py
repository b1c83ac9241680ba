"""Decision rules (ILAC-G8 guarded acceptance vs simple) and what blocks a PASS.

The guarded cases are ILAC-G8:09/2019 §4.2.2's picture typed in by hand:
an upper limit L with guard band w = U: value ≤ L − U accepts, value > L + U
rejects, anything between is "conformity indeterminate" (CONDITIONAL here).
"""

from __future__ import annotations

import json
import shutil

import pytest

from gyrocal.metrology.decision import (
    Decision,
    DecisionRule,
    Verdict,
    decide,
    instrument_blockers,
    instrument_findings,
    overall_verdict,
)
from gyrocal.metrology.sanity import SanityCheck
from gyrocal.reports.acceptance import evaluate_acceptance
from gyrocal.reports.build import build_report
from tests.support.verdicts import judged

OK = [SanityCheck("scale factor near nominal", True, "fine")]


@pytest.mark.parametrize(("value", "expected"), [
    (7.0, Decision.PASS),          # 7 + 2 ≤ 10
    (8.0, Decision.PASS),          # exactly L − U: still accepted
    (9.0, Decision.CONDITIONAL),   # inside L ± U, below L
    (11.5, Decision.CONDITIONAL),  # inside L ± U, above L
    (12.5, Decision.FAIL),         # beyond L + U
])
def test_guarded_upper_limit(value, expected):
    decision, guard = decide(value, 2.0, 10.0, "max", DecisionRule.GUARDED)
    assert decision is expected and guard == 2.0


def test_guarded_lower_limit_and_simple_rule():
    assert decide(11.0, 2.0, 10.0, "min", DecisionRule.GUARDED)[0] is Decision.CONDITIONAL
    assert decide(12.0, 2.0, 10.0, "min", DecisionRule.GUARDED)[0] is Decision.PASS
    assert decide(7.9, 2.0, 10.0, "min", DecisionRule.GUARDED)[0] is Decision.FAIL
    # simple: the bare value against the limit, U ignored
    assert decide(9.9, 2.0, 10.0, "max", DecisionRule.SIMPLE) == (Decision.PASS, 0.0)
    assert decide(10.1, 2.0, 10.0, "max", DecisionRule.SIMPLE)[0] is Decision.FAIL
    # guarded without an uncertainty cannot accept
    assert decide(1.0, None, 10.0, "max", DecisionRule.GUARDED)[0] is Decision.CONDITIONAL


def test_guarded_acceptance_entry_gives_conditional_within_u_of_its_limit():
    results = {"asymmetry_ppm": -4.5,
               "uncertainty": {"asymmetry_ppm": {"U": 1.0}, "nonlinearity.rms_pct": {"U": 0.1}},
               "nonlinearity": {"rms_pct": 0.5}}
    limits = [{"name": "asym", "metric": "asymmetry_ppm", "max": 5.0, "decision_rule": "guarded"},
              {"name": "nl", "metric": "nonlinearity.rms_pct", "max": 1.0,
               "decision_rule": "guarded"},
              {"name": "nl simple", "metric": "nonlinearity.rms_pct", "max": 0.55}]
    verdicts = evaluate_acceptance(results, limits, [])
    asym, nl, simple = verdicts
    assert asym.decision is Decision.CONDITIONAL and asym.passed is False   # |−4.5| + 1 > 5
    assert asym.guard_band == 1.0 and asym.decision_rule is DecisionRule.GUARDED
    assert nl.decision is Decision.PASS and nl.passed is True
    assert simple.decision is Decision.PASS and simple.decision_rule is DecisionRule.SIMPLE
    assert asym.to_json()["pass"] is False and asym.to_json()["decision"] == "CONDITIONAL"
    verdict = overall_verdict(OK, verdicts, [])
    assert verdict.overall is Verdict.CONDITIONAL and verdict.conditional == ("asym",)
    assert verdict.to_json()["conditional"] == ["asym"]


def _instruments(**table):
    return {"table": {"serial": "SIM0001", "calibration_due": "2027-03-31",
                      "calibration_overdue": False,
                      "description": "ACUTRONIC,ACUTROL3000-SIM,SIM0001,1.0"} | table,
            "chamber": {"serial": "12-3456", "calibration_overdue": False,
                        "description": "Watlow F4 (model register 5270), serial 12-3456, x"}}


def test_expired_reference_blocks_pass_unless_waived():
    passing = [judged(Decision.PASS, "a")]
    assert overall_verdict(OK, passing, instrument_blockers(_instruments())).overall.value == "PASS"
    expired = _instruments(calibration_due="2001-01-01", calibration_overdue=True)
    verdict = overall_verdict(OK, passing, instrument_blockers(expired))
    assert verdict.overall is Verdict.BLOCKED
    assert "reference instrument out of calibration" in verdict.blocked_because[0]
    waived = _instruments(calibration_overdue=True, calibration_waiver="re-certified 2026-11-01")
    assert overall_verdict(OK, passing, instrument_blockers(waived)).overall.value == "PASS"
    assert "re-certified" in instrument_findings(waived).checks["table"].waived
    assert "waived" not in waived["table"]          # the instruments given are left as they are
    # INVALID and FAIL still take precedence
    bad = [SanityCheck("bias finite", False, "nan")]
    assert overall_verdict(bad, passing, instrument_blockers(expired)).overall.value == "INVALID"


def test_reported_serial_differing_from_declared_is_flagged_and_blocks():
    # IEEE 488.2 *IDN? reply: manufacturer,model,serial,firmware (field 3 is the serial)
    swapped = _instruments(serial="ACT-0999")
    before = json.dumps(swapped, sort_keys=True)
    found = instrument_findings(swapped)
    blockers = found.blockers
    assert found.checks["table"].identity_mismatch is True
    assert found.checks["table"].reported_serial == "SIM0001"
    assert found.checks["chamber"].identity_mismatch is False
    assert found.checks["table"].to_json() == {"reported_serial": "SIM0001",
                                               "identity_mismatch": True}
    assert json.dumps(swapped, sort_keys=True) == before      # not changed in place
    assert [b.role for b in blockers] == ["table"]
    assert "'ACT-0999'" in blockers[0].reason


#: the gyro's identity as the STIM300 driver describes it after N<CR> and I<CR> (TS1524 §8.1-8.2)
STIM300_SAYS = ("STIM300 datagram 0x94 (rate, temperature) (25-byte frames), 2000 Hz, 921600 baud, "
                "unit under test: x axis; unit part number 84167-0000000-S0M rev G, "
                "serial N00000000004242; configuration confirmed (C, TS1524 §8.3): ...")


def test_a_unit_under_test_reporting_another_serial_is_flagged_as_the_table_is():
    # the gyro's declared serial is the procedure's unit_under_test.serial (reports/build.py)
    gyro = {"make": "unit under test", "serial": "N00000000001111", "calibration_due": None,
            "calibration_overdue": False, "description": STIM300_SAYS}
    found = instrument_findings(_instruments() | {"gyro": gyro})
    assert found.checks["gyro"].to_json() == {"reported_serial": "N00000000004242",
                                              "identity_mismatch": True}
    assert [b.role for b in found.blockers] == ["gyro"]
    assert "'N00000000001111'" in found.blockers[0].reason
    assert "'N00000000004242'" in found.blockers[0].reason
    same = instrument_findings(_instruments() | {"gyro": gyro | {"serial": "n00000000004242"}})
    assert same.checks["gyro"].identity_mismatch is False and same.blockers == ()


@pytest.mark.parametrize("description", [
    STIM300_SAYS.replace("serial N00000000004242", "serial: not confirmed (no answer to I, "
                                                   "TS1524 §8.2)"),
    # an analog gyro read through a DMM: the chain's *IDN? is the meter's, not the unit's
    "analog input chain: DC volts through Keysight Technologies,34465A,MY59001234,A.03.01; "
    "last calibrated 2026-01-05; range 10 V, NPLC 0.02, sample timer 500 Hz",
])
def test_a_gyro_that_does_not_say_its_serial_is_not_checked(description):
    gyro = {"serial": "N00000000001111", "calibration_overdue": False, "description": description}
    found = instrument_findings({"gyro": gyro})
    assert found.checks["gyro"].reported_serial is None
    assert found.blockers == ()


def test_rebuilt_report_of_a_run_with_an_expired_table_is_not_pass(smoke_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    plan_path = run / "plan.json"
    plan = json.loads(plan_path.read_text())
    plan["station"]["instruments"]["table"]["identity"]["calibration_due"] = "2001-01-01"
    plan_path.write_text(json.dumps(plan))
    results = build_report(run)
    assert results["verdict"]["overall"] == "BLOCKED"
    assert results["instruments"]["table"]["calibration_overdue"] is True
    assert all(a["pass"] for a in results["acceptance"])       # the limits themselves pass
