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

from gyrocal.reports.decision import DEFAULT_RULE, Decision, DecisionRule, decide

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
                        notes: list[str]) -> list[dict[str, Any]]:
    """One verdict per limit: {name, metric, kind, limit, unit, value, pass, decision, …}.

    ``limits`` are plan.json's acceptance entries ({name, metric, max|min, unit,
    decision_rule}); the rule (decision.py) uses the metric's expanded
    uncertainty from results["uncertainty"]. ``pass`` is true only for PASS.
    A null or non-numeric value fails, and a note says which metric was missing.
    """
    uncertainty = results.get("uncertainty") or {}
    verdicts = []
    for limit in limits:
        kind = "max" if limit.get("max") is not None else "min"
        bound = float(limit[kind])
        value = lookup_metric(results, limit["metric"])
        number = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
            else None
        rule = DecisionRule(limit.get("decision_rule") or DEFAULT_RULE.value)
        expanded = (uncertainty.get(limit["metric"]) or {}).get("U")
        guard = 0.0
        if number is None or not math.isfinite(number):
            decision = Decision.FAIL
            number = None
            notes.append(f"acceptance {limit['name']!r}: {limit['metric']} was not computed, "
                         "so the limit fails")
        elif kind == "max" and number < 0 and limit["metric"] not in SIGNED_METRICS:
            decision = Decision.FAIL
            notes.append(f"acceptance {limit['name']!r}: {limit['metric']} = {number:g} cannot "
                         "be negative, so the limit fails")
        elif kind == "max" and limit["metric"] in SIGNED_METRICS:
            # a signed figure's limit is on its size
            decision, guard = decide(abs(number), expanded, bound, kind, rule)
        else:
            decision, guard = decide(number, expanded, bound, kind, rule)
        verdicts.append({"name": limit["name"], "metric": limit["metric"], "kind": kind,
                         "limit": bound, "unit": limit.get("unit"), "value": number,
                         "pass": decision is Decision.PASS, "decision": decision.value,
                         "decision_rule": rule.value, "U": expanded, "guard_band": guard})
    return verdicts


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
