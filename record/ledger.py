"""The station ledger: where a run's chain head is kept outside the run folder.

A signed journal proves a folder's history is the station's, but not that it
is the *whole* folder the station left: a run folder deleted, or swapped for
an older copy of itself (a seal from before the last resume), leaves nothing
inside any folder to contradict it. So every seal also appends one line to an
append-only ledger beside the station's private key (``station.key`` →
``station.ledger.jsonl``), out of reach of whoever edits run folders: run id,
run folder, the seal's sequence number, the chain head after the seal, the
key fingerprint and the seal's signature. The latest line per run id is what
that run's journal must end with.

``gyrocal verify RUN_DIR --ledger FILE`` checks one run against it;
``gyrocal ledger FILE`` walks every run the ledger knows and names the
missing and the changed ones.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrocal.record.journal import sha256_bytes

LEDGER_SUFFIX = ".ledger.jsonl"


class LedgerError(Exception):
    """A ledger that cannot be read (names the file and line)."""


@dataclass(frozen=True)
class LedgerEntry:
    line: int
    run_id: str
    run_dir: Path
    seq: int
    chain_head: str
    key_fingerprint: str
    signature: str


def ledger_path_for(private_key: Path) -> Path:
    """The ledger beside a station key: ``station.key`` → ``station.ledger.jsonl``."""
    return private_key.with_name(private_key.stem + LEDGER_SUFFIX)


def append_entry(ledger: Path, run_dir: Path, seal: dict[str, Any], chain_head: str) -> None:
    """One line for one seal, appended and fsynced (O_APPEND: never rewrites what is there)."""
    line = json.dumps({"run_id": seal.get("run_id"), "run_dir": str(run_dir.resolve()),
                       "seq": seal.get("seq"), "chain_head": chain_head,
                       "key_fingerprint": seal.get("key_fingerprint"),
                       "signature": seal.get("signature"), "wall_time": seal.get("wall_time")},
                      sort_keys=True, separators=(",", ":")).encode() + b"\n"
    descriptor = os.open(ledger, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
    try:
        os.write(descriptor, line)
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def read_ledger(ledger: Path) -> dict[str, LedgerEntry]:
    """The latest entry per run id."""
    if not ledger.is_file():
        raise LedgerError(f"{ledger}: ledger not found")
    latest: dict[str, LedgerEntry] = {}
    for number, raw in enumerate(ledger.read_bytes().splitlines(), start=1):
        try:
            item = json.loads(raw)
            entry = LedgerEntry(number, str(item["run_id"]), Path(item["run_dir"]),
                                int(item["seq"]), str(item["chain_head"]),
                                str(item["key_fingerprint"]), str(item["signature"]))
        except (ValueError, KeyError, TypeError) as exc:
            raise LedgerError(f"{ledger}:{number}: not a ledger line ({exc})") from None
        latest[entry.run_id] = entry
    return latest


def journal_head(journal: Path) -> tuple[int, str]:
    """(line count, SHA-256 of the last line) of a journal as it is on disk."""
    lines = journal.read_bytes().splitlines(keepends=True)
    return (len(lines), sha256_bytes(lines[-1])) if lines else (0, "")


def check_against(entry: LedgerEntry, journal: Path, ledger: Path) -> str | None:
    """What differs between a run's journal and its latest ledger line (None: it matches)."""
    where = f"{ledger}:{entry.line}"
    if not journal.is_file():
        return f"{journal}: missing; {where} records run {entry.run_id} ending at line {entry.seq}"
    count, head = journal_head(journal)
    if count != entry.seq or head != entry.chain_head:
        return (f"{journal}: ends at line {count} with head {head[:16]}…, but {where} records "
                f"run {entry.run_id} ending at line {entry.seq} with head {entry.chain_head[:16]}…"
                ": the run folder was replaced, cut or extended after its last seal")
    return None
