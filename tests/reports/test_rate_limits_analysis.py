"""Input-rate limits analysis (analysis/rate/rate_limits.py) on hand-typed dwell means."""

from __future__ import annotations

import math

import pytest

from gyrocal.analysis.rate.rate_limits import LimitDwell, rate_limits_section


def walk(outputs: dict[float, float], tolerance_pct: float = 1.0, fit: int = 2) -> list[LimitDwell]:
    return [LimitDwell(f"s{rate:+g}", 25.0, rate, out, tolerance_pct, fit)
            for rate, out in outputs.items()]


def test_the_maximum_is_the_last_rate_that_follows_the_line_each_way():
    # SF 2, bias 0.1; saturates at +500 output (250 deg/s) and −400 (200 deg/s)
    rates = [50.0, 100.0, 150.0, 200.0, 250.0, 300.0]
    outputs = {r: 2 * r + 0.1 for r in rates if 2 * r <= 500} | {300.0: 500.1}
    outputs |= {-r: max(-2 * r, -400.0) + 0.1 for r in rates}
    section = rate_limits_section(walk(outputs), []).to_json()
    positive, negative = section["tests"]
    assert positive["fit_sf"] == pytest.approx(2.0) and positive["fit_bias"] == pytest.approx(0.1)
    assert (positive["max_dps"], positive["next_dps"]) == (250.0, 300.0)
    assert (negative["max_dps"], negative["next_dps"]) == (200.0, 250.0)
    # -250 deg/s: output -400 against -500 fitted: 20 % off
    assert negative["points"][4]["deviation_pct"] == pytest.approx(20.0)
    assert positive["u_dps"] == pytest.approx(50.0 / math.sqrt(12.0))
    assert section["max_positive_dps"] == 250.0 and section["max_negative_dps"] == 200.0


def test_a_rate_within_the_tolerance_follows_and_one_beyond_it_does_not():
    outputs = {50.0: 50.0, 100.0: 100.0, 150.0: 148.6, 200.0: 197.0}   # 0.93 %, 1.5 %
    section = rate_limits_section(walk(outputs), []).to_json()
    assert [p["follows"] for p in section["tests"][0]["points"]] == [True, True, True, False]
    assert section["max_positive_dps"] == 150.0 and section["max_negative_dps"] is None


def test_an_unreached_limit_is_a_lower_bound_with_no_uncertainty_and_a_note():
    notes: list[str] = []
    section = rate_limits_section(walk({50.0: 50.0, 100.0: 100.0, 150.0: 150.0}), notes).to_json()
    test = section["tests"][0]
    assert test["max_dps"] == 150.0 and test["next_dps"] is None and test["U_dps"] is None
    assert "a lower bound" in notes[0]


def test_a_walk_on_a_line_far_from_the_nominal_sf_makes_the_run_invalid():
    from gyrocal.metrology.decision import Decision
    from gyrocal.metrology.sanity import check_physics, verdict
    from tests.support.verdicts import judged

    section = rate_limits_section(walk({50.0: -50.0, 100.0: -100.0, 150.0: -150.0}), []).to_json()
    results = {"unit_under_test": {"nominal_scale_factor": 1.0}, "rate_limits": section}
    check = next(c for c in check_physics(results) if c.name.startswith("rate-limit walk"))
    assert not check.ok and "SF -1" in check.detail
    assert verdict(check_physics(results), [judged(Decision.PASS)]).overall.value == "INVALID"
