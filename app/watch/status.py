"""``gyrocal status RUN_DIR [--json]``: where a run is, for a person or a script.

Built on :func:`read_snapshot`, the same reader as the live page, so the two
never disagree. The text is for a person at a terminal (state, step n/N,
ETA, how long since the journal last moved, who holds the run); ``--json`` is
the same snapshot for scripts, with stable keys.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gyrocal.app.watch.snapshot import RunSnapshot, read_snapshot
from gyrocal.orchestrator.engine import PAUSE_FILE
from gyrocal.record.journal import JournalEvent
from gyrocal.units import format_hms

#: How every view of a dry run says what it is (status, the live page, the report's banner).
SIMULATED_TEXT = "SIMULATED run: simulated instruments, not a calibration"

_STATE_TEXT = {
    "interrupted": "interrupted (process gone; resumable)",
    "faulted": "faulted (instruments safe; resumable)",
}


def status_text(snap: RunSnapshot) -> str:
    state = _STATE_TEXT.get(snap.state, snap.state)
    if snap.paused:
        state = f"PAUSED (delete {Path(snap.run_dir) / PAUSE_FILE} to go on)"
    lines = [f"run {snap.run_id}  {snap.run_dir}"]
    if snap.simulated:
        lines.append(f"  {SIMULATED_TEXT}")
    lines += [
             f"  state: {snap.state}" + ("" if state == snap.state else f" — {state}"),
             f"  unit: {snap.serial or '-'}  procedure: {snap.procedure or '-'}"]
    nxt = f"; next: {snap.current_step}" if snap.current_step else ""
    lines.append(f"  steps: {snap.steps_done}/{snap.step_count} completed{nxt}")
    lines.append(f"  ETA (plan, procedure time): {format_hms(snap.eta_s, live=True)}")
    if snap.last_event_age_s is not None:
        age = f"  last event: {format_hms(snap.last_event_age_s, live=True)} ago"
        if snap.events:
            last = snap.events[-1]
            age += f" (#{last.seq} {last.event} {last.step_id})".rstrip()
        if snap.stale:
            age += "  WARNING: the controller is alive but the journal has not moved — check it"
        lines.append(age)
    if snap.lock is not None:
        lines.append(f"  held by: {snap.lock.describe()}")
    else:
        lines.append("  held by: " + ("a live controller" if snap.live else "nobody"))
    retries = sum(1 for e in snap.events if e.event == JournalEvent.RETRY)
    lines.append(f"  faults: {len(snap.faults)}; retries (last {len(snap.events)} events): "
                 f"{retries}")
    if snap.last_fault:
        lines.append(f"  last fault: {snap.last_fault}")
    return "\n".join(lines)


def cmd_status(args: argparse.Namespace) -> int:
    snap = read_snapshot(Path(args.run_dir))
    if getattr(args, "json", False):
        print(json.dumps(snap.to_json(), indent=2, allow_nan=False))
    else:
        print(status_text(snap))
    return 0
