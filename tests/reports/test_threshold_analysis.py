"""Threshold and resolution analysis (analysis/rate/threshold.py) on hand-typed dwell means."""

from __future__ import annotations

import math

import pytest

from gyrocal.analysis.rate.threshold import ThresholdDwell, bracket, increments, threshold_section


def dwells(base_dps: float, pairs: list[tuple[float, float]], ref_means: list[float],
           sem: float = 1e-4) -> list[ThresholdDwell]:
    """base, base+δ₁, base, … with the given output means (nominal SF 1)."""
    out = []
    for index, (delta, mean) in enumerate(pairs):
        out.append(ThresholdDwell(f"ref{index}", 23.0, base_dps, base_dps, ref_means[index], sem,
                                  0.95, 0.5))
        out.append(ThresholdDwell(f"d{index}", 23.0, base_dps, base_dps + delta, mean, sem,
                                  0.95, 0.5))
    out.append(ThresholdDwell(f"ref{len(pairs)}", 23.0, base_dps, base_dps, ref_means[-1], sem,
                              0.95, 0.5))
    return out


def test_an_increment_is_judged_against_the_mean_of_its_neighbouring_base_dwells():
    # refs drift 0.000, 0.002: the increment's change is 0.011 - 0.001 = 0.010
    found = increments(dwells(0.0, [(0.01, 0.011)], [0.0, 0.002]), 1.0)
    assert found[0].measured_dps == pytest.approx(0.010)
    assert found[0].u_dps == pytest.approx(math.sqrt(1e-8 + 2e-8 / 4))
    assert found[0].resolved and found[0].within


def test_a_change_below_the_confidence_quantile_is_not_resolved():
    # z = 1.5e-4 / 1.2247e-4 = 1.22 < 1.645 (95 % one-sided)
    found = increments(dwells(0.0, [(0.0002, 0.00015)], [0.0, 0.0]), 1.0)
    assert not found[0].resolved


def test_a_resolved_change_far_from_the_commanded_one_is_not_within():
    # 0.01 commanded, 0.004 measured: 60 % short of it, the fraction allows 50 %
    found = increments(dwells(0.0, [(0.01, 0.004)], [0.0, 0.0]), 1.0)
    assert found[0].resolved and not found[0].within and not found[0].passes


def test_the_threshold_is_the_smallest_increment_from_which_every_larger_one_passes():
    # 0.02 passes by a fluke, 0.03 does not, 0.04 on: threshold 0.04, bracket (0.03, 0.04]
    means = [0.0, 0.02, 0.0, 0.04, 0.05]
    pairs = list(zip([0.01, 0.02, 0.03, 0.04, 0.05], means, strict=True))
    result = bracket(increments(dwells(0.0, pairs, [0.0] * 6), 1.0))
    assert (result.threshold_dps, result.below_dps) == (0.04, 0.03)
    assert result.u_dps == pytest.approx(0.01 / math.sqrt(12))


def test_no_passing_increment_gives_no_threshold_and_a_note():
    notes: list[str] = []
    section = threshold_section(dwells(0.0, [(0.01, 0.0), (0.02, 0.0)], [0.0] * 3), 1.0, notes)
    assert section.threshold_dps is None and section.tests[0].threshold_dps is None
    assert section.to_json()["tests"][0]["U_dps"] is None
    assert "above the largest" in notes[0]


def test_zero_base_is_the_threshold_and_a_non_zero_base_the_resolution():
    found = dwells(0.0, [(0.01, 0.0), (0.02, 0.02)], [0.0] * 3) + \
        dwells(10.0, [(0.01, 10.01), (0.02, 10.02)], [10.0] * 3)
    section = threshold_section(found, 1.0, [])
    assert section.threshold_dps == 0.02 and section.resolution_dps == 0.01
    assert [t["standard_test"].split()[0] for t in section.to_json()["tests"]] == \
        ["threshold", "resolution"]
