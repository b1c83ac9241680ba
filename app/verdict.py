"""The verdict on the console: one line per acceptance limit with value ± U, and the exit code.

Shared by ``run``, ``resume`` and ``report``: the same results.json prints the same
lines whichever command built it.
"""

from __future__ import annotations

from typing import Any

from gyrocal.errors import EXIT_ACCEPTANCE_FAILED, EXIT_OK
from gyrocal.metrology.decision import DecisionRule
from gyrocal.reports.acceptance import AcceptanceVerdict


def print_verdict(results: dict[str, Any]) -> int:
    """The acceptance lines and the overall verdict; exit 1 unless PASS."""
    acceptance = [AcceptanceVerdict.from_json(item) for item in results.get("acceptance", [])]
    for item in acceptance:
        print(f"  {item.decision.value}  {item.name}: {verdict_line(item)}")
    verdict = results.get("verdict") or {}
    overall = verdict.get("overall")
    if overall == "INVALID":
        print("  INVALID: the numbers are not physically possible, no limit was judged:")
        for reason in verdict["invalid_because"]:
            print(f"    {reason}")
    for reason in verdict.get("blocked_because", []):
        print(f"  BLOCKED: {reason}")
    if overall == "INCOMPLETE":
        print(f"  INCOMPLETE: not evaluated: {', '.join(verdict.get('not_evaluated') or [])}")
    failed = any(not a.passed for a in acceptance)
    return EXIT_ACCEPTANCE_FAILED if failed or overall not in (None, "PASS") else EXIT_OK


def verdict_line(item: AcceptanceVerdict) -> str:
    """``value ± U unit (max L unit, rule)``: U on every line, so a value near its limit shows it."""
    unit = f" {item.unit}" if item.unit else ""
    rule = item.decision_rule.value
    guard = (f", guard band {item.guard_band:.2g}{unit}"
             if item.decision_rule is DecisionRule.GUARDED and item.guard_band else "")
    limit = f"({item.kind} {item.limit:.6g}{unit}, {rule} rule{guard})"
    if item.identifiable is False:
        bound = item.upper_bound_95
        shown = f"{bound:.3g}{unit}" if bound is not None else "unknown"
        return f"not identifiable from this record (95 % upper bound {shown}) {limit}"
    if item.value is None:
        return f"{item.why or 'not computed'} {limit}"
    u_text = f" ± {item.U:.2g}" if item.U is not None else " (U not stated)"
    return f"{item.value:.6g}{u_text}{unit} {limit}"
