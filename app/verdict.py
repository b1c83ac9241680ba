"""The verdict on the console: one line per acceptance limit with value ± U, and the exit code.

Shared by ``run``, ``resume`` and ``report``: the same results.json prints the same
lines whichever command built it.
"""

from __future__ import annotations

from typing import Any

from gyrocal.errors import EXIT_ACCEPTANCE_FAILED, EXIT_OK


def print_verdict(results: dict[str, Any]) -> int:
    """The acceptance lines and the overall verdict; exit 1 unless PASS."""
    for item in results.get("acceptance", []):
        verdict = item.get("decision") or ("PASS" if item["pass"] else "FAIL")
        print(f"  {verdict}  {item['name']}: {verdict_line(item)}")
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
    failed = any(not a.get("pass") for a in results.get("acceptance", []))
    return EXIT_ACCEPTANCE_FAILED if failed or overall not in (None, "PASS") else EXIT_OK


def verdict_line(item: dict[str, Any]) -> str:
    """``value ± U unit (max L unit, rule)``: U on every line, so a value near its limit shows it."""
    unit = f" {item['unit']}" if item.get("unit") else ""
    rule = item.get("decision_rule") or "simple"
    guard = (f", guard band {item['guard_band']:.2g}{unit}"
             if rule == "guarded" and item.get("guard_band") else "")
    limit = f"({item['kind']} {item['limit']:.6g}{unit}, {rule} rule{guard})"
    if item.get("identifiable") is False:
        bound = item.get("upper_bound_95")
        shown = f"{bound:.3g}{unit}" if isinstance(bound, (int, float)) else "unknown"
        return f"not identifiable from this record (95 % upper bound {shown}) {limit}"
    if item.get("value") is None:
        return f"{item.get('why') or 'not computed'} {limit}"
    u_text = f" ± {item['U']:.2g}" if isinstance(item.get("U"), (int, float)) else \
        " (U not stated)"
    return f"{item['value']:.6g}{u_text}{unit} {limit}"
