"""Resuming a run whose steps are all recorded: close it, or repair a closed run's tail.

A kill can fall after ``run_completed`` (the steps, the safe state and the
report are recorded) and before ``run_closed``, or inside a later report
rebuild, certificate or seal. Nothing physical is left to do there — the rig
was returned to its safe state before ``steps_done`` — so ``gyrocal resume``
connects to nothing: it sets aside what the cut left on disk (``strays``),
rebuilds the report if its files are not the recorded ones, writes the
closing line the run lacks, and seals the session. The history then verifies
as the uninterrupted run's would, plus the lines that say what was repaired.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gyrocal.record.journal import Journal, JournalEvent
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.signing import SEAL_EVENT, Signer
from gyrocal.record.strays import report_matches_record, set_aside

#: Builds the report through the given open journal (``reports.build.build_report``).
ReportBuilder = Callable[[RunFolder, Journal], dict[str, Any]]


@dataclass
class Repair:
    """What resuming a completed run did (printed by ``resume``)."""

    closed_now: bool = False
    report_rebuilt: bool = False
    sealed: bool = False
    set_aside: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = [f"set aside {path} (never recorded; kept under orphans/)" for path in self.set_aside]
        if self.report_rebuilt:
            out.append("report rebuilt (its files were not the recorded ones)")
        if self.closed_now:
            out.append("run closed (it was completed, then cut off before its closing line)")
        if self.sealed:
            out.append("session sealed")
        return out or ["nothing to repair"]


def steps_completed_run(events: list[dict[str, Any]]) -> bool:
    """Has the run recorded ``run_completed`` (every step, the safe state, the report)?"""
    return any(e.get("event") == JournalEvent.RUN_COMPLETED for e in events)


def close_completed(folder: RunFolder, signer: Signer | None, build: ReportBuilder) -> Repair:
    """Close (or repair) a run whose journal has ``run_completed``; the caller holds its lock."""
    repair = Repair()
    journal = folder.open_journal()          # a torn tail is set aside (and journaled) here
    try:
        manifest = folder.read_manifest()
        moved = set_aside(folder.path, journal, folder.journal_events(), manifest)
        repair.set_aside = [str(e["path"]) for e in moved]
        events = folder.journal_events()
        if not report_matches_record(folder.path, events):
            build(folder, journal)
            repair.report_rebuilt = True
        events = folder.journal_events()
        if not any(e.get("event") == JournalEvent.RUN_CLOSED for e in events):
            completed = [e for e in events if e.get("event") == JournalEvent.RUN_COMPLETED][-1]
            journal.append(JournalEvent.RUN_CLOSED, outcome="completed", closed_by="resume")
            folder.update_manifest(state="done", ended_at=completed.get("ended_at"))
            repair.closed_now = True
        if signer is not None and folder.journal_events()[-1].get("event") != SEAL_EVENT:
            signer.seal(journal, str(manifest.get("run_id", "")), reason="resume closed the run")
            repair.sealed = True
    finally:
        folder.close()
    return repair
