"""A judged acceptance limit for tests of the overall verdict (only its decision matters there)."""

from __future__ import annotations

from gyrocal.metrology.decision import Decision, DecisionRule
from gyrocal.reports.acceptance import AcceptanceVerdict


def judged(decision: Decision, name: str = "limit") -> AcceptanceVerdict:
    return AcceptanceVerdict(name, "asymmetry_ppm", "max", 1.0, "ppm", DecisionRule.SIMPLE,
                             decision)
