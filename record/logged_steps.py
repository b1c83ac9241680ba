"""Which logged steps of a run count, and which hold is the Allan record: one rule for all readers.

The report, ``gyrocal analyze allan`` on a run folder and the discrepancy
workflow must agree on what a run measured. A step may have been repeated
(bad data, a resume): only its last completed attempt with samples counts.
The Allan record is the longest completed static/allan hold — by samples,
ties to the earlier step.
"""

from __future__ import annotations

from typing import Any

from gyrocal.record.journal import JournalEvent
from gyrocal.record.step_kind import StepKind

#: Plan step kinds that are holds at rest: the Allan record is chosen among them, and the
#: uncertainty budget pools them per temperature for the bias.
HOLD_KINDS = (StepKind.STATIC, StepKind.ALLAN)


def completed_attempts(events: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """step_id → its last step_completed event that logged chunks (a repeat supersedes)."""
    done: dict[str, dict[str, Any]] = {}
    for event in events:
        if event.get("event") == JournalEvent.STEP_COMPLETED and event.get("chunks"):
            done[event["step_id"]] = event
    return done


def longest_hold(plan_steps: list[dict[str, Any]], events: list[dict[str, Any]]
                 ) -> dict[str, Any] | None:
    """The step_completed event of the longest completed hold, or None when there is none."""
    kinds = {s["step_id"]: s.get("kind") for s in plan_steps}
    holds = [e for sid, e in completed_attempts(events).items() if kinds.get(sid) in HOLD_KINDS]
    return max(holds, key=lambda e: int(e.get("samples") or 0), default=None)
