"""Which attempt of a step counts, and which hold is the Allan record: one rule for all readers.

The engine (which steps a resume skips, which attempt number comes next), the
report, ``gyrocal analyze allan`` on a run folder, the discrepancy workflow
and the live page must agree on what a run did. A step may have been repeated
(bad data, a resume): its last ``step_completed`` event is the attempt that
counts, and a completed step is never run again. The reports read the counted
attempts that logged samples. The Allan record is the longest completed
static/allan hold — by samples, ties to the earlier step.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from gyrocal.record.journal import JournalEvent
from gyrocal.record.step_kind import StepKind

#: Plan step kinds that are holds at rest: the Allan record is chosen among them, and the
#: uncertainty budget pools them per temperature for the bias.
HOLD_KINDS = (StepKind.STATIC, StepKind.ALLAN)


def counted_attempts(events: Iterable[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """step_id → its last ``step_completed`` event: the attempt that counts (a repeat supersedes).

    In the order the steps first completed. The engine's resume skips exactly these steps.
    """
    done: dict[str, dict[str, Any]] = {}
    for event in events:
        if event.get("event") == JournalEvent.STEP_COMPLETED and "step_id" in event:
            done[str(event["step_id"])] = event
    return done


def completed_attempts(events: Iterable[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """step_id → the counted attempt of each step that logged samples (its ``chunks``)."""
    return {sid: e for sid, e in counted_attempts(events).items() if e.get("chunks")}


def attempts_started(events: Iterable[dict[str, Any]]) -> dict[str, int]:
    """step_id → the highest attempt number any ``step_started`` event gave it.

    A new attempt is numbered after it: chunks of earlier attempts are journaled with
    their hashes and must never be overwritten.
    """
    last: dict[str, int] = {}
    for event in events:
        if event.get("event") == JournalEvent.STEP_STARTED and "step_id" in event:
            step_id = str(event["step_id"])
            last[step_id] = max(last.get(step_id, 0), int(event.get("attempt", 1)))
    return last


def bad_attempts(events: Iterable[dict[str, Any]]) -> dict[str, int]:
    """step_id → how many of its attempts were journaled bad (``step_bad``).

    A resumed dry run draws the random streams of the attempt the uninterrupted run
    was at: one more than the step's bad attempts (``engine.Rehearsal``).
    """
    bad: dict[str, int] = {}
    for event in events:
        if event.get("event") == JournalEvent.STEP_BAD and "step_id" in event:
            bad[event["step_id"]] = bad.get(event["step_id"], 0) + 1
    return bad


def longest_hold(kinds: dict[str, StepKind], events: list[dict[str, Any]]
                 ) -> dict[str, Any] | None:
    """The step_completed event of the longest completed hold, or None when there is none.

    ``kinds``: step_id → kind, from the plan record.
    """
    holds = [e for sid, e in completed_attempts(events).items() if kinds.get(sid) in HOLD_KINDS]
    return max(holds, key=lambda e: int(e.get("samples") or 0), default=None)
