"""results.json assembly helpers and the acceptance evaluation.

QA signs a run off against its acceptance limits, so the verdict must be
traceable: each limit names a key path of results.json, the value found
there is shown next to the limit, and a metric that could not be computed
fails (a missing number is never a pass) with a note saying why.
"""

from __future__ import annotations

import json
import math
from typing import Any

from gyrocal.metrology.decision import DEFAULT_RULE, Decision, DecisionRule, decide
from gyrocal.metrology.metrics import metric_needs

#: The keys interfaces.md requires in report/results.json.
REQUIRED_KEYS = ("unit_under_test", "scale_factor", "scale_factor_ls", "nonlinearity",
                 "asymmetry_ppm", "sf_temperature", "bias", "bias_temperature", "allan",
                 "compensation", "acceptance")


def lookup_metric(results: dict[str, Any], metric: str) -> Any:
    """Value at a dotted key path (``allan.fit.B_dph``); None when any part is missing/null."""
    node: Any = results
    for part in metric.split("."):
        if not isinstance(node, dict) or node.get(part) is None:
            return None
        node = node[part]
    return node


#: Metrics whose sign is physical (a max limit bounds their magnitude); every other
#: metric with a max limit is a size or a spread, and a negative value of it is impossible.
SIGNED_METRICS = frozenset({"asymmetry_ppm", "scale_factor_ls.bias",
                            "sf_temperature.sensitivity_ppm_per_c",
                            "bias_temperature.sensitivity_dph_per_c"})


def evaluate_acceptance(results: dict[str, Any], limits: list[dict[str, Any]],
                        notes: list[str], measured: frozenset[str] | None = None
                        ) -> list[dict[str, Any]]:
    """One verdict per limit: {name, metric, kind, limit, unit, value, pass, decision, …}.

    ``limits`` are plan.json's acceptance entries ({name, metric, max|min, unit,
    decision_rule}); the rule (decision.py) uses the metric's expanded
    uncertainty from results["uncertainty"]. ``pass`` is true only for PASS.
    ``measured`` (what the completed steps measured, ``metrology/metrics.py``
    ``needs``): a limit whose metric needs more is NOT EVALUATED, whatever number
    some other step gave. A noise term the record cannot identify is judged by its
    95 % upper bound (PASS only if that bound is within a max limit), never as 0.
    A null or non-numeric value of a measured metric fails, with a note.
    """
    uncertainty = results.get("uncertainty") or {}
    verdicts = []
    for limit in limits:
        kind = "max" if limit.get("max") is not None else "min"
        bound = float(limit[kind])
        rule = DecisionRule(limit.get("decision_rule") or DEFAULT_RULE.value)
        expanded = (uncertainty.get(limit["metric"]) or {}).get("U")
        entry = {"name": limit["name"], "metric": limit["metric"], "kind": kind,
                 "limit": bound, "unit": limit.get("unit"), "value": None,
                 "decision_rule": rule.value, "U": expanded, "guard_band": 0.0}
        decision = _judge(results, entry, rule, measured, notes)
        entry.update({"pass": decision is Decision.PASS, "decision": decision.value})
        verdicts.append(entry)
    return verdicts


def _judge(results: dict[str, Any], entry: dict[str, Any], rule: DecisionRule,
           measured: frozenset[str] | None, notes: list[str]) -> Decision:
    """The decision for one limit; fills ``value``, ``guard_band`` and any ``why`` in ``entry``."""
    metric, kind, bound, label = entry["metric"], entry["kind"], entry["limit"], entry["name"]
    needs = metric_needs(metric)
    if measured is not None and needs is not None and needs[0] not in measured:
        entry["why"] = f"not measured: it needs {needs[1]}, completed"
        notes.append(f"acceptance {label!r}: {metric} NOT EVALUATED ({entry['why']})")
        return Decision.NOT_EVALUATED
    value = lookup_metric(results, metric)
    number = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else None
    if number is None or not math.isfinite(number):
        notes.append(f"acceptance {label!r}: {metric} was not computed, so the limit fails")
        return Decision.FAIL
    term = metric.removeprefix("allan.fit.")
    allan = results.get("allan") or {}
    if metric.startswith("allan.fit.") and (allan.get("identifiable") or {}).get(term) is False:
        return _judge_unidentifiable(entry, allan, term, notes)
    entry["value"] = number
    if kind == "max" and number < 0 and metric not in SIGNED_METRICS:
        notes.append(f"acceptance {label!r}: {metric} = {number:g} cannot be negative, "
                     "so the limit fails")
        return Decision.FAIL
    judged = abs(number) if kind == "max" and metric in SIGNED_METRICS else number
    decision, entry["guard_band"] = decide(judged, entry["U"], bound, kind, rule)
    return decision


def _judge_unidentifiable(entry: dict[str, Any], allan: dict[str, Any], term: str,
                          notes: list[str]) -> Decision:
    upper = (allan.get("upper_bound_95") or {}).get(term)
    entry["identifiable"] = False
    entry["upper_bound_95"] = upper
    if entry["kind"] == "max" and isinstance(upper, (int, float)) and math.isfinite(upper) \
            and upper <= entry["limit"]:
        entry["why"] = (f"not identifiable from this record; its 95 % upper bound {upper:.3g} "
                        "is within the limit")
        return Decision.PASS
    entry["why"] = ("not identifiable from this record" +
                    (f"; its 95 % upper bound {upper:.3g} does not settle the limit"
                     if isinstance(upper, (int, float)) else ""))
    notes.append(f"acceptance {entry['name']!r}: {entry['metric']} NOT EVALUATED ({entry['why']})")
    return Decision.NOT_EVALUATED


def finite_or_none(value: Any) -> Any:
    """JSON has no NaN/inf: such a number becomes null (recursively)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return finite_or_none(value.item())
    return value


def results_bytes(results: dict[str, Any]) -> bytes:
    """Canonical, NaN-free encoding of results.json."""
    return json.dumps(finite_or_none(results), indent=2, allow_nan=False).encode() + b"\n"
