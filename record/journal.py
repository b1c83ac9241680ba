"""Append-only run journal with a SHA-256 hash chain.

QA must be able to prove that nothing in a run's history was edited or
removed afterwards. Each line is one JSON event carrying ``prev_sha256``, the
hash of the previous line's bytes (the first line chains to a fixed genesis
value), and every line is written and fsynced before the call returns, so a
crash loses at most the event being written. (A dry run's journal, opened with
``durable=False``, is written line by line but fsynced only when closed: a
kill -9 loses nothing the process wrote, since the page cache outlives it; only
a power cut would, and a simulated night has nothing a power cut could lose
that a rerun with the same seed would not give back.) A torn last line (power cut mid
write) is detected on reopen and set aside in ``journal.torn`` rather than
silently dropped or silently trusted.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

from gyrocal.record.crash import at_journal_line

GENESIS_SHA256 = "0" * 64
#: Where a torn last line is kept (beside the journal), and its journal event's fields.
TORN_FILE = "journal.torn"


class JournalEvent(str, Enum):
    """Every event name a run journal holds: the catalogue, in one place.

    A ``str`` enum: an event written as ``JournalEvent.STEP_COMPLETED`` is the
    text ``"step_completed"`` in the file, and readers may compare either.
    The report, verify, status and the live page read these names, so a
    misspelt event is an AttributeError here instead of a silently unmatched
    string there.
    """

    RUN_STARTED = "run_started"
    INSTRUMENT_IDENTIFIED = "instrument_identified"
    #: what the gyro said when asked for its configuration at connect (a STIM300's C<CR>),
    #: or that it did not answer
    GYRO_CONFIGURATION = "gyro_configuration"
    #: what the gyro said when asked who it is at connect (a STIM300's N<CR> and I<CR>)
    GYRO_IDENTITY = "gyro_identity"
    #: what the gyro sent unasked when it started after a power-on (a STIM300's start-up
    #: datagrams: part number, serial, configuration, bias trim offset)
    GYRO_START_UP = "gyro_start_up"
    PREFLIGHT_OK = "preflight_ok"
    RESUMED = "resumed"
    RESTORE_CONDITIONS = "restore_conditions"
    #: a resumed dry run put its simulated station back into the state a completed step
    #: journaled (``sim_state`` of the step_completed line ``from_seq``; engine.Rehearsal)
    SIM_STATE_RESTORED = "sim_state_restored"
    #: a dry run's state after a step that acts after its step_completed line (a drive-off,
    #: frequency-response, tilt or magnetic step; engine.ACTS_AFTER_COMPLETED)
    SIM_STATE_SAVED = "sim_state_saved"
    STEP_STARTED = "step_started"
    STEP_COMPLETED = "step_completed"
    STEP_BAD = "step_bad"
    CHUNK_WRITTEN = "chunk_written"
    GYRO_IMPLAUSIBLE = "gyro_implausible"
    RETRY = "retry"
    PAUSED = "paused"
    UNPAUSED = "unpaused"
    OPERATOR_NEEDED = "operator_needed"
    OPERATOR_CONFIRMED = "operator_confirmed"
    MOUNT_RECHECK = "mount_recheck"
    #: the table's drive switched off (interlock opened) or back on for a table_interference step
    TABLE_DRIVE = "table_drive"
    #: the table entered synthesis mode (a frequency_response step): the sinusoid and its start
    TABLE_SYNTHESIS = "table_synthesis"
    FAULT_INJECTED = "fault_injected"
    FAULT = "fault"
    INTERRUPTED = "interrupted"
    SAFE_STATE = "safe_state"
    SUPPLY_READ = "supply_read"          # the unit's supply read back (orchestrator/unit_power.py)
    COIL_FIELD = "coil_field"            # the coil's field set/read back/off (magnetic steps)
    TABLE_POSITION = "table_position"    # the table reached a tilt step's angle (position mode)
    #: a turn-on step switched the unit off and on: the output-on time and the first frame's
    UNIT_POWER_CYCLE = "unit_power_cycle"
    SIMULATOR_ERROR = "simulator_error"
    STEPS_DONE = "steps_done"
    REPORT_WRITTEN = "report_written"
    RUN_COMPLETED = "run_completed"
    RUN_CLOSED = "run_closed"
    NOTIFIED = "notified"
    SEALED = "sealed"
    #: a completed run's return to the station's safe state, read back (before steps_done)
    RETURNED_SAFE = "returned_safe"
    #: a file on disk the history never recorded (a chunk or temporary file a crash left
    #: between its write and its journal line), moved to ``orphans/`` and named here
    ORPHAN_SET_ASIDE = "orphan_set_aside"
    #: a torn last line (a write cut by a crash) moved to ``journal.torn``
    TORN_TAIL_SET_ASIDE = "torn_tail_set_aside"
    #: a calibration certificate written from the report, with its SHA-256
    CERTIFICATE_WRITTEN = "certificate_written"

    def __str__(self) -> str:     # the name as written in the file (Python 3.10 has no StrEnum)
        return self.value


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: Path, chunk_bytes: int = 1 << 20) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(chunk_bytes):
            digest.update(block)
    return digest.hexdigest()


class JournalError(Exception):
    """The journal on disk does not verify (names the line)."""


@dataclass(frozen=True)
class JournalEntry:
    line_no: int
    event: dict[str, Any]
    raw: bytes


def _encode(event: dict[str, Any]) -> bytes:
    return json.dumps(event, sort_keys=True, separators=(",", ":"), allow_nan=False).encode() + b"\n"


def read_journal(path: Path) -> Iterator[JournalEntry]:
    """Yield entries, checking the hash chain; raises :class:`JournalError` naming the first bad line."""
    prev = GENESIS_SHA256
    with open(path, "rb") as handle:
        for line_no, raw in enumerate(handle, start=1):
            if not raw.endswith(b"\n"):
                raise JournalError(f"{path}:{line_no}: incomplete last line (torn write)")
            try:
                event = json.loads(raw)
            except json.JSONDecodeError as exc:
                raise JournalError(f"{path}:{line_no}: not JSON: {exc.msg}") from None
            except ValueError:  # bytes that are not UTF-8 text
                raise JournalError(f"{path}:{line_no}: not JSON text (invalid UTF-8 bytes)") from None
            if not isinstance(event, dict):
                raise JournalError(f"{path}:{line_no}: not a journal event (a JSON "
                                   f"{type(event).__name__}, expected an object)")
            if event.get("prev_sha256") != prev:
                raise JournalError(
                    f"{path}:{line_no}: hash chain broken: prev_sha256 is "
                    f"{event.get('prev_sha256')!r}, the previous line hashes to {prev}"
                )
            prev = sha256_bytes(raw)
            yield JournalEntry(line_no, event, raw)


class Journal:
    """Writer for ``journal.jsonl``; reopening continues the chain after the last good line."""

    def __init__(self, path: Path, durable: bool = True) -> None:
        self.path = Path(path)
        #: fsync every line (a station's run); False only for dry runs (module docstring)
        self.durable = durable
        self._last_sha256 = GENESIS_SHA256
        self.count = 0
        #: Called with each event after it is durably written (e.g. notifications).
        self.listeners: list[Callable[[dict[str, Any]], None]] = []
        #: the torn tail set aside on opening, journaled as soon as the chain has a first line
        self._torn: dict[str, Any] | None = None
        if self.path.exists():
            self._recover()
        self._handle = open(self.path, "ab", buffering=0)  # noqa: SIM115 - held for the run
        if self._torn is not None and self.count:
            self._journal_torn()

    def _recover(self) -> None:
        data = self.path.read_bytes()
        cut = data.rfind(b"\n") + 1
        if cut < len(data):
            # A torn tail: keep its bytes for the auditor, then truncate to the last full line.
            torn_path = self.path.parent / TORN_FILE
            with open(torn_path, "ab") as torn:
                torn.write(data[cut:] + b"\n")
                os.fsync(torn.fileno())
            with open(self.path, "r+b") as handle:
                handle.truncate(cut)
                os.fsync(handle.fileno())
            self._torn = {"path": TORN_FILE, "bytes": len(data) - cut,
                          "torn_sha256": sha256_file(torn_path)}
        for entry in read_journal(self.path):
            self._last_sha256 = sha256_bytes(entry.raw)
            self.count = entry.line_no

    def _journal_torn(self) -> None:
        """Name the set-aside tail in the history, so verify expects ``journal.torn`` and its hash."""
        torn, self._torn = self._torn, None
        self.append(JournalEvent.TORN_TAIL_SET_ASIDE, **(torn or {}))

    @property
    def last_sha256(self) -> str:
        return self._last_sha256

    def append(self, name: JournalEvent | str, /, **fields: Any) -> dict[str, Any]:
        """Write one event durably and return it as written."""
        event = {"seq": self.count + 1, "wall_time": time.time(), "event": str(name), **fields}
        event["prev_sha256"] = self._last_sha256
        self._write(_encode(event))
        for listener in self.listeners:
            listener(event)
        if self._torn is not None:     # the tail torn before the first line could chain
            self._journal_torn()
        return event

    def _write(self, raw: bytes) -> None:
        at_journal_line("before", self.count + 1)
        self._write_whole(raw)       # unbuffered: in the kernel once this returns
        if self.durable:
            os.fsync(self._handle.fileno())
        self._last_sha256 = sha256_bytes(raw)
        self.count += 1
        at_journal_line("after", self.count)

    def _write_whole(self, raw: bytes) -> None:
        """The whole line or none of it: a full disk (or a file-size limit) can make the
        kernel take part of a write and refuse the rest; what was taken is cut off again,
        so the history never holds half a line the chain has not counted."""
        fd = self._handle.fileno()
        start = os.fstat(fd).st_size
        view, written = memoryview(raw), 0
        try:
            while written < len(raw):
                taken = self._handle.write(view[written:])
                if not taken:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
                written += taken
        except OSError:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, start)
            raise

    def append_signed(self, name: JournalEvent | str, sign, /, **fields: Any) -> dict[str, Any]:
        """Append an event whose ``signature`` field is ``sign(event)`` over its other fields.

        Used for the seal (:mod:`gyrocal.record.signing`): the event's
        ``prev_sha256`` is the chain head the signature vouches for.
        """
        event = {"seq": self.count + 1, "wall_time": time.time(), "event": str(name), **fields}
        event["prev_sha256"] = self._last_sha256
        event["signature"] = sign(event)
        self._write(_encode(event))
        return event

    @property
    def closed(self) -> bool:
        return self._handle.closed

    def close(self) -> None:
        if not self._handle.closed:
            if not self.durable:
                os.fsync(self._handle.fileno())
            self._handle.close()

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
