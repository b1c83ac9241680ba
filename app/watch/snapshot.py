"""Where a run is, read from its folder alone: the one reader behind ``status`` and ``watch``.

The controller may be another process, on another machine sharing the
folder, or dead after a crash; so everything here comes from what the run
wrote to disk (manifest, ``plan.json``, ``journal.jsonl``, sample chunks) and
nothing from the controller's memory. The journal is read leniently (a line
still being written, or torn by a crash, is left out): auditing the chain is
``gyrocal verify``'s job, watching must keep working while the run writes.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from gyrocal.record.event_text import describe_event
from gyrocal.record.journal import JournalEvent
from gyrocal.record.locks import LockHolder, holder
from gyrocal.record.logged_steps import counted_attempts
from gyrocal.record.plan_record import PlanRecordMissing, load_plan_record
from gyrocal.record.run_folder import JOURNAL, MANIFEST, RunFolderError

#: Journal events a person watching the run must see at once.
FAULT_EVENTS = frozenset({JournalEvent.FAULT, JournalEvent.INTERRUPTED, JournalEvent.STEP_BAD,
                          JournalEvent.SIMULATOR_ERROR})
#: With the controller alive, this long without a journal event is worth a warning.
STALE_AFTER_S = 15 * 60.0


@dataclass(frozen=True)
class PlanStep:
    step_id: str
    kind: str
    setpoint_c: float | None
    rate_dps: float
    expected_s: float


@dataclass(frozen=True)
class EventLine:
    seq: int
    wall_time: float
    event: str
    step_id: str
    detail: str
    fault: bool


@dataclass(frozen=True)
class RunSnapshot:
    run_dir: str
    run_id: str
    serial: str
    procedure: str
    state: str                 # created | running | paused | faulted | done | interrupted
    live: bool                 # a controller process is known to be alive
    steps_done: int
    step_count: int
    current_step: str | None   # the step being run (or next to run)
    current_index: int         # 1-based index of current_step; 0 before the first
    eta_s: float | None        # procedure time still to go by the plan
    last_event_age_s: float | None
    stale: bool
    lock: LockHolder | None    # who holds the run folder (record/locks.py)
    last_fault: str | None
    plan: list[PlanStep] = field(default_factory=list)
    completed: list[str] = field(default_factory=list)
    events: list[EventLine] = field(default_factory=list)
    faults: list[EventLine] = field(default_factory=list)
    #: a dry run against simulated instruments (run_started's ``sim``): never a calibration
    simulated: bool = False

    @property
    def paused(self) -> bool:
        return self.state == "paused"

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["paused"] = self.paused
        return data


def read_events(run_dir: Path) -> list[dict[str, Any]]:
    """Every complete journal line as a dict; a partial last line is left for the next look."""
    path = Path(run_dir) / JOURNAL
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise RunFolderError(f"{path}: cannot be read ({exc.strerror or exc}); "
                             "the run folder is damaged") from None
    events = []
    for line_no, raw in enumerate(data.split(b"\n")[:-1], start=1):
        try:
            event = json.loads(raw)
        except ValueError:
            raise RunFolderError(f"{path}:{line_no}: not a JSON journal line; "
                                 f"`gyrocal verify {run_dir}` says more") from None
        if isinstance(event, dict):
            events.append(event)
    return events


def read_json_object(path: Path) -> dict[str, Any]:
    """A JSON file that must hold an object: anything else names the file (exit 2), never a crash."""
    try:
        data = json.loads(path.read_bytes())
    except IsADirectoryError:
        raise RunFolderError(f"{path}: a folder where the run keeps a file") from None
    except (ValueError, UnicodeDecodeError):
        raise RunFolderError(f"{path}: not valid JSON") from None
    except OSError as exc:
        raise RunFolderError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not isinstance(data, dict):
        raise RunFolderError(f"{path}: holds a JSON {type(data).__name__}, not the object "
                             "a run writes there; the run folder is damaged") from None
    return data


def _list_of(path: Path, key: str, value: Any, item: type) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, item) for v in value):
        raise RunFolderError(f"{path}: {key!r} is not a list of {item.__name__}; "
                             "the run folder is damaged")
    return value


def read_plan(run_dir: Path) -> list[PlanStep]:
    """The plan's steps from plan.json (through the record's one reader); none before it exists."""
    try:
        record = load_plan_record(run_dir)
    except PlanRecordMissing:
        return []
    return [PlanStep(s.step_id, str(s.kind), s.setpoint_c, s.rate_dps, s.expected_s or 0.0)
            for s in record.steps]


def read_snapshot(run_dir: Path, *, now: float | None = None, last_events: int = 20) -> RunSnapshot:
    run_dir = Path(run_dir)
    manifest_path = run_dir / MANIFEST
    if not run_dir.is_dir() or not manifest_path.exists():
        raise RunFolderError(f"{run_dir}: not a run folder ({MANIFEST} missing)")
    manifest = read_json_object(manifest_path)
    now = time.time() if now is None else now
    events = read_events(run_dir)
    plan = read_plan(run_dir)
    step_ids = [s.step_id for s in plan] or [
        str(s) for s in _list_of(manifest_path, "steps", manifest.get("steps"), str)]
    done = list(counted_attempts(events))     # the engine's rule: a completed step counts once
    done_set = set(done)
    remaining = [s for s in step_ids if s not in done_set]
    current = remaining[0] if remaining else None
    current_index = step_ids.index(current) + 1 if current else len(step_ids)

    lock = holder(run_dir)
    state = str(manifest.get("state") or "created")
    live = lock is not None or (state in ("running", "paused") and _pid_alive(manifest.get("pid")))
    if state in ("running", "paused") and not live:
        state = "interrupted"
    elif state == "running" and _paused_in_journal(events):
        state = "paused"

    expected = {s.step_id: s.expected_s for s in plan}
    eta_s = sum(expected.get(s, 0.0) for s in remaining) if plan else None
    last_wall = _num(events[-1].get("wall_time")) if events else None
    last_age = now - last_wall if last_wall is not None else None
    stale = bool(live and last_age is not None and last_age > STALE_AFTER_S and state != "paused")
    lines = [_line(e) for e in events]
    faults = [line for line in lines if line.fault]
    uut = manifest.get("unit_under_test") or {}
    return RunSnapshot(
        run_dir=str(run_dir), run_id=str(manifest.get("run_id", "")),
        serial=str(uut.get("serial", "")) if isinstance(uut, dict) else str(uut),
        procedure=str(manifest.get("procedure", "") or _procedure_name(events)),
        state=state, live=live, steps_done=len(done_set), step_count=len(step_ids),
        current_step=current, current_index=current_index, eta_s=eta_s,
        last_event_age_s=last_age, stale=stale, lock=lock,
        last_fault=(str(manifest["last_fault"]) if manifest.get("last_fault")
                    else (faults[-1].detail if faults else None)),
        plan=plan, completed=done, events=lines[-last_events:], faults=faults[-last_events:],
        simulated=_simulated(events, manifest),
    )


def _simulated(events: list[dict[str, Any]], manifest: dict[str, Any]) -> bool:
    """As run_started recorded it (signed history); the manifest's mode before the first line."""
    for event in events:
        if event.get("event") == JournalEvent.RUN_STARTED:
            return bool(event.get("sim"))
    return manifest.get("mode") == "sim"


def _paused_in_journal(events: list[dict[str, Any]]) -> bool:
    for event in reversed(events):
        if event.get("event") == JournalEvent.PAUSED:
            return True
        if event.get("event") in (JournalEvent.UNPAUSED, JournalEvent.STEP_STARTED, JournalEvent.RESUMED):
            return False
    return False


def _procedure_name(events: list[dict[str, Any]]) -> str:
    for event in events:
        if event.get("event") == JournalEvent.RUN_STARTED:
            return str(event.get("procedure", ""))
    return ""


def _line(event: dict[str, Any]) -> EventLine:
    name = str(event.get("event", "?"))
    detail = describe_event(event)
    seq = _num(event.get("seq"))
    return EventLine(int(seq) if seq is not None else 0, _num(event.get("wall_time")) or 0.0,
                     name, str(event.get("step_id") or event.get("before_step") or ""),
                     str(detail), name in FAULT_EVENTS)


def _num(value: Any) -> float | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _pid_alive(pid: Any) -> bool:
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except PermissionError:
        return True
    except OSError:
        return False
    return True


