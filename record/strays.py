"""What belongs in a run folder, and what to do with a file nothing recorded.

A file is *recorded* when a journal event names it with its SHA-256 (a chunk
by ``chunk_written``, the report by the last ``report_written``, a
certificate by ``certificate_written``, a set-aside file by
``orphan_set_aside``, a torn journal tail by ``torn_tail_set_aside``) or when
``run_started`` fixed it (the input copies, ``plan.json``). A kill between a
file's write and its journal line leaves a file on disk that the history
never recorded — a finished chunk, or the temporary file of an atomic write.
Such a file is never counted and never silently dropped: the next controller
(a resume, a report rebuild) moves it to ``orphans/`` and journals where it
went, with its hash, so verify can name it in its account. verify uses the
same list to name any file nobody recorded (a planted ``journal.torn``, a
stray chunk).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrocal.record.atomic import TMP_SUFFIX, fsync_dir
from gyrocal.record.journal import Journal, JournalEvent, sha256_file
from gyrocal.record.plan_record import PLAN_RECORD

ORPHANS = "orphans"
#: Files that hold no data anything reads for the record: the controller's lock, the
#: operator's pause request and remount confirmation.
CONTROL_FILES = ("controller.lock", "PAUSE", "CONFIRM")
#: Files of the folder's frame, checked against the journal by verify in their own right.
FRAME_FILES = ("manifest.json", "journal.jsonl", PLAN_RECORD)
REPORT_DIR = "report"


@dataclass(frozen=True)
class Stray:
    """A file on disk that no journal event records (or, for the report, records otherwise)."""

    path: str       # relative to the run folder
    reason: str


def recorded_files(events: list[dict[str, Any]], manifest: dict[str, Any]) -> dict[str, str | None]:
    """Relative path → recorded SHA-256 (None: checked by verify against run_started)."""
    files: dict[str, str | None] = dict.fromkeys(FRAME_FILES)
    for entry in (manifest.get("inputs") or {}).values():
        if isinstance(entry, dict) and entry.get("copy"):
            files[str(entry["copy"])] = None
    reports = [e for e in events if e.get("event") == JournalEvent.REPORT_WRITTEN]
    for event in events:
        name = event.get("event")
        if name == JournalEvent.CHUNK_WRITTEN:
            files[str(event.get("path"))] = event.get("sha256")
        elif name == JournalEvent.ORPHAN_SET_ASIDE:
            files[str(event.get("moved_to"))] = event.get("sha256")
        elif name == JournalEvent.TORN_TAIL_SET_ASIDE:
            files[str(event.get("path"))] = event.get("torn_sha256")
        elif name == JournalEvent.CERTIFICATE_WRITTEN and event.get("in_run_folder"):
            files[str(event.get("path"))] = event.get("sha256")
    if reports:
        files.update((reports[-1].get("files") or {}).items())
    return files


def files_on_disk(root: Path) -> list[str]:
    """Every regular file under the run folder, relative, sorted."""
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def unrecorded(root: Path, events: list[dict[str, Any]], manifest: dict[str, Any]) -> list[Stray]:
    """Files no event records, and report files whose bytes are not the recorded ones."""
    recorded = recorded_files(events, manifest)
    strays = []
    for rel in files_on_disk(root):
        if rel in CONTROL_FILES:
            continue
        if rel not in recorded:
            strays.append(Stray(rel, _why(rel)))
        elif rel.startswith(f"{REPORT_DIR}/") and recorded[rel] is not None \
                and sha256_file(root / rel) != recorded[rel]:
            strays.append(Stray(rel, "report file whose bytes are not the ones its last journal "
                                     "event recorded (a report write cut short)"))
    return strays


def _why(rel: str) -> str:
    if Path(rel).name.endswith(TMP_SUFFIX):
        return "temporary file of a write cut short (never renamed into place)"
    if rel.startswith("samples/"):
        return "sample chunk written but never journaled (cut between its write and its line)"
    if rel.startswith(f"{REPORT_DIR}/"):
        return "report file no report_written event recorded (a report write cut short)"
    return "file no journal event records"


def set_aside(root: Path, journal: Journal, events: list[dict[str, Any]],
              manifest: dict[str, Any]) -> list[dict[str, Any]]:
    """Move every unrecorded file to ``orphans/`` and journal each move; returns the events.

    Moved, not deleted: whatever a crash left is kept for the auditor, and the
    move is itself recorded, so the folder holds only recorded files again.
    Nothing under ``orphans/`` is ever read as data.
    """
    written = []
    for stray in unrecorded(root, events, manifest):
        source = root / stray.path
        target = _free_name(root / ORPHANS / stray.path)
        digest, size = sha256_file(source), source.stat().st_size
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(source, target)
        fsync_dir(target.parent)
        fsync_dir(source.parent)
        written.append(journal.append(
            JournalEvent.ORPHAN_SET_ASIDE, path=stray.path,
            moved_to=str(target.relative_to(root)), sha256=digest, bytes=size,
            reason=stray.reason))
    return written


def _free_name(path: Path) -> Path:
    if not path.exists():
        return path
    for n in range(1, 10_000):
        candidate = path.with_name(f"{path.name}.{n}")
        if not candidate.exists():
            return candidate
    raise FileExistsError(f"{path}: no free name for a set-aside file")


def report_matches_record(root: Path, events: list[dict[str, Any]]) -> bool:
    """Is every file of the last ``report_written`` on disk with its recorded hash?"""
    reports = [e for e in events if e.get("event") == JournalEvent.REPORT_WRITTEN]
    if not reports:
        return False
    return all((root / rel).is_file() and sha256_file(root / rel) == digest
               for rel, digest in (reports[-1].get("files") or {}).items())
