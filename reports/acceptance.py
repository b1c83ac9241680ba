"""The acceptance evaluation: one typed verdict per limit of the procedure.

QA signs a run off against its acceptance limits, so the verdict must be
traceable: each limit names a metric of the catalogue (``metrology/metrics.py``),
the value found there is shown next to the limit, and a metric that could not be
computed fails (a missing number is never a pass) with a note saying why.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from gyrocal.metrology.decision import DEFAULT_RULE, Decision, DecisionRule, decide
from gyrocal.metrology.metrics import (
    METRICS,
    Metric,
    Need,
    as_number,
    metric_number,
    reported_uncertainty,
)


@dataclass(frozen=True)
class AcceptanceVerdict:
    """One limit judged: results.json ``acceptance[i]`` (interfaces.md), typed."""

    name: str
    metric: str
    kind: str                       # "max" or "min"
    limit: float
    unit: str | None
    decision_rule: DecisionRule
    decision: Decision
    value: float | None = None
    U: float | None = None          # noqa: N815 - the metric's expanded uncertainty (GUM)
    guard_band: float = 0.0
    why: str | None = None
    #: False for a noise term this record cannot identify (judged by its 95 % upper bound)
    identifiable: bool | None = None
    upper_bound_95: float | None = None

    @property
    def passed(self) -> bool:
        return self.decision is Decision.PASS

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name, "metric": self.metric, "kind": self.kind, "limit": self.limit,
            "unit": self.unit, "value": self.value, "decision_rule": self.decision_rule.value,
            "U": self.U, "guard_band": self.guard_band}
        if self.identifiable is not None:
            out |= {"identifiable": self.identifiable, "upper_bound_95": self.upper_bound_95}
        if self.why is not None:
            out["why"] = self.why
        return out | {"pass": self.passed, "decision": self.decision.value}

    @classmethod
    def from_json(cls, item: Mapping[str, Any]) -> AcceptanceVerdict:
        """A verdict as results.json holds it (older files: ``pass`` without ``decision``)."""
        decision = item.get("decision") or ("PASS" if item.get("pass") else "FAIL")
        identifiable = item.get("identifiable")
        return cls(str(item["name"]), str(item["metric"]), str(item["kind"]),
                   float(item["limit"]), item.get("unit"),
                   DecisionRule(item.get("decision_rule") or DEFAULT_RULE.value),
                   Decision(decision), as_number(item.get("value")), as_number(item.get("U")),
                   as_number(item.get("guard_band")) or 0.0, item.get("why"),
                   identifiable if isinstance(identifiable, bool) else None,
                   as_number(item.get("upper_bound_95")))


def evaluate_acceptance(results: Mapping[str, Any], limits: list[Mapping[str, Any]],
                        notes: list[str], measured: frozenset[Need] | None = None
                        ) -> list[AcceptanceVerdict]:
    """One verdict per limit, in the limits' order.

    ``limits`` are plan.json's acceptance entries ({name, metric, max|min, unit,
    decision_rule}); the rule (decision.py) uses the metric's expanded
    uncertainty from results["uncertainty"]. ``measured`` (what the completed
    steps measured, the catalogue's ``needs``): a limit whose metric needs more is
    NOT EVALUATED, whatever number some other step gave. A noise term the record
    cannot identify is judged by its 95 % upper bound (PASS only if that bound is
    within a max limit), never as 0. A null or non-numeric value of a measured
    metric fails, with a note.
    """
    verdicts = []
    for limit in limits:
        kind = "max" if limit.get("max") is not None else "min"
        metric = METRICS.get(limit["metric"])
        pending = AcceptanceVerdict(
            limit["name"], limit["metric"], kind, float(limit[kind]), limit.get("unit"),
            DecisionRule(limit.get("decision_rule") or DEFAULT_RULE.value),
            Decision.NOT_EVALUATED,
            U=None if metric is None else reported_uncertainty(results, metric)[1])
        if metric is None:      # a plan.json older than the catalogue's current names
            notes.append(f"acceptance {pending.name!r}: {pending.metric} is not a metric "
                         "results.json has, so the limit fails")
            verdicts.append(replace(pending, decision=Decision.FAIL))
            continue
        verdicts.append(_judge(results, metric, pending, measured, notes))
    return verdicts


def _judge(results: Mapping[str, Any], metric: Metric, pending: AcceptanceVerdict,
           measured: frozenset[Need] | None, notes: list[str]) -> AcceptanceVerdict:
    """The verdict for one limit: its decision, value, guard band and any ``why``."""
    label = pending.name
    if measured is not None and metric.needs not in measured:
        why = f"not measured: it needs {metric.needs.text}, completed"
        notes.append(f"acceptance {label!r}: {metric.key} NOT EVALUATED ({why})")
        return replace(pending, why=why)
    number = metric_number(results, metric)
    if number is None:
        notes.append(f"acceptance {label!r}: {metric.key} was not computed, so the limit fails")
        return replace(pending, decision=Decision.FAIL)
    allan = results.get("allan") or {}
    term = metric.noise_term
    if term is not None and (allan.get("identifiable") or {}).get(term) is False:
        return _judge_unidentifiable(pending, allan, term, notes)
    if pending.kind == "max" and number < 0 and not metric.signed:
        notes.append(f"acceptance {label!r}: {metric.key} = {number:g} cannot be negative, "
                     "so the limit fails")
        return replace(pending, value=number, decision=Decision.FAIL)
    judged = abs(number) if pending.kind == "max" and metric.signed else number
    decision, guard_band = decide(judged, pending.U, pending.limit, pending.kind,
                                  pending.decision_rule)
    return replace(pending, value=number, decision=decision, guard_band=guard_band)


def _judge_unidentifiable(pending: AcceptanceVerdict, allan: Mapping[str, Any], term: str,
                          notes: list[str]) -> AcceptanceVerdict:
    upper = (allan.get("upper_bound_95") or {}).get(term)
    number = as_number(upper)
    pending = replace(pending, identifiable=False, upper_bound_95=upper)
    if pending.kind == "max" and number is not None and math.isfinite(number) \
            and number <= pending.limit:
        why = f"not identifiable from this record; its 95 % upper bound {upper:.3g} is within the limit"
        return replace(pending, why=why, decision=Decision.PASS)
    why = ("not identifiable from this record" +
           (f"; its 95 % upper bound {upper:.3g} does not settle the limit"
            if number is not None else ""))
    notes.append(f"acceptance {pending.name!r}: {pending.metric} NOT EVALUATED ({why})")
    return replace(pending, why=why)
