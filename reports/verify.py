"""``gyrocal verify``: is this run folder the complete, unedited history the station wrote?

An auditor signs off on a folder, so verify must catch what an editor of the
folder could do — not only a changed byte, but a shortened history, forged
events, a loosened limit with its hash "fixed", a report that no longer
follows from the samples. In order, first failure wins:

1. **the journal**: every line JSON, every ``prev_sha256`` the hash of the
   line before (a malformed line is named by number, never a traceback);
2. **its shape**: it opens with ``run_started`` (seq 1) and — for a finished
   run — contains ``run_closed``; after that only report rebuilds and seals;
   a run without ``run_closed`` is INCOMPLETE, never OK;
3. **what run_started fixed**: the SHA-256 of every input copy and of
   ``plan.json``, and the run's identity (operator, unit, station, mode,
   seed, software); the manifest must agree with them (it is mutable run
   state, so it is checked against the journal, not trusted);
4. **samples**: every journaled chunk on disk with its hash, every chunk on
   disk journaled, every completed step's chunks journaled; the manifest's
   instrument identities are the journal's ``instrument_identified``;
5. **the report**: every file of ``report/`` recorded by the last
   ``report_written`` with its hash; the report's own signature block (over
   the chain head that ``report_written`` chains to and the numbers); and the
   report's numbers recomputed from the samples (a report that does not
   follow from the data fails; a key the report lacks because an older
   gyrocal built it is named, not compared);
   then every certificate (``certificate_written``) and every file set aside
   in ``orphans/`` after a crash (``orphan_set_aside``) on disk with its
   hash — named in the account, never counted — and no file in the folder
   that no event records (a planted ``journal.torn``, a stray chunk);
6. **the seals**: the journal's last line is a ``sealed`` event whose Ed25519
   signature covers the chain head. With ``--key`` (the station's public key
   from QA's records) every seal must verify with it: a history recomputed by
   someone without the private key fails. Without ``--key`` verify says
   plainly that it checked integrity, not authenticity.

What it cannot catch: someone holding the station's private key can write a
consistent, signed, false history. Keep the key with the station.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from gyrocal.record.journal import (
    JournalError,
    JournalEvent,
    read_journal,
    sha256_bytes,
    sha256_file,
)
from gyrocal.record.ledger import LedgerError, check_against, read_ledger
from gyrocal.record.plan_record import PLAN_RECORD
from gyrocal.record.run_folder import (
    IDENTITY_KEYS,
    JOURNAL,
    SAMPLES,
    RunFolder,
    identified_instruments,
)
from gyrocal.record.signing import (
    SEAL_EVENT,
    fingerprint,
    load_public_key,
    report_signature_valid,
    seal_signature_valid,
)
from gyrocal.record.strays import files_on_disk, unrecorded
from gyrocal.reports.build import compute_results, read_run
from gyrocal.reports.results import RECOMPUTED_KEYS, finite_or_none, results_bytes

#: Events a finished run may still gain after ``run_closed``: report rebuilds, certificates,
#: what a cut-off session left set aside, and their seals.
AFTER_CLOSE = (JournalEvent.REPORT_WRITTEN, JournalEvent.CERTIFICATE_WRITTEN,
               JournalEvent.ORPHAN_SET_ASIDE, JournalEvent.TORN_TAIL_SET_ASIDE, SEAL_EVENT)
#: Relative tolerance of the recomputation (the same code on the same samples: rounding only).
RECOMPUTE_RTOL = 1e-9


@dataclass
class VerifyResult:
    """``failure`` names the first problem (None when everything checks)."""

    run_dir: Path
    failure: str | None = None
    checked: dict[str, int] = field(default_factory=dict)
    unchecked: list[str] = field(default_factory=list)
    authenticity: str = ""
    #: "path sha256 number" of each certificate the history records (latest per path)
    certificates: list[str] = field(default_factory=list)
    #: files a crash left unrecorded, set aside in orphans/ and never counted
    orphans: list[str] = field(default_factory=list)
    #: results keys this gyrocal computes that the report lacks (built by an older gyrocal):
    #: not compared, named
    not_in_report: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.failure is None

    def summary(self) -> str:
        counts = ", ".join(f"{n} {what}" for what, n in self.checked.items())
        extra = f" (not checked: {'; '.join(self.unchecked)})" if self.unchecked else ""
        lines = [f"{self.run_dir}: OK — complete, every hash matches, the numbers follow from "
                 f"the samples: {counts}{extra}"]
        lines += [f"  certificate {c}" for c in self.certificates]
        lines += [f"  set aside, never counted: {o}" for o in self.orphans]
        if self.not_in_report:
            lines.append(f"  not in this report (older gyrocal), not compared: "
                         f"{', '.join(self.not_in_report)}")
        return "\n".join([*lines, f"  {self.authenticity}"])


class _Mismatch(Exception):
    pass


def _check_file(path: Path, expected: str | None, what: str) -> None:
    if not path.is_file():
        raise _Mismatch(f"{path}: missing ({what})")
    if not expected:
        raise _Mismatch(f"{path}: no recorded SHA-256 to check it against ({what})")
    actual = sha256_file(path)
    if actual != expected:
        raise _Mismatch(f"{path}: SHA-256 {actual} does not match {expected} recorded in {what}")


def verify_run_folder(run_dir: str | Path, public_key: str | Path | None = None,
                      recompute: bool = True, ledger: str | Path | None = None) -> VerifyResult:
    """Check a run folder; raises RunFolderError when this is not a run folder at all.

    ``public_key``: the station's PEM public key; without it, authenticity is
    not checked (and the result says so). ``recompute=False`` skips step 5's
    recomputation of the numbers (for callers that just built them).
    ``ledger``: the station ledger; the journal must end where its latest
    line for this run says (a folder replaced by an older or cut copy fails).
    """
    folder = RunFolder.open(Path(run_dir))
    result = VerifyResult(folder.path)
    try:
        key = load_public_key(Path(public_key)) if public_key is not None else None
        events = _journal(folder, result)
        started = _shape(folder, events, result)
        _inputs_and_identity(folder, started, events, result)
        _samples(folder, events, result)
        _report(folder, events, result, recompute, key)
        _set_aside_and_certificates(folder, events, result)
        _nothing_unrecorded(folder, events, result)
        _seals(events, key, result)
        if ledger is not None:
            _ledger(folder, events, Path(ledger), result)
    except _Mismatch as exc:
        result.failure = str(exc)
    except LedgerError as exc:
        result.failure = str(exc)
    return result


def _ledger(folder: RunFolder, events: list[dict[str, Any]], ledger: Path,
            result: VerifyResult) -> None:
    run_id = str(events[0].get("run_id"))
    entry = read_ledger(ledger).get(run_id)
    if entry is None:
        raise _Mismatch(f"{ledger}: no line for run {run_id}: this run was not sealed on the "
                        "station that keeps this ledger")
    difference = check_against(entry, folder.path / JOURNAL, ledger)
    if difference:
        raise _Mismatch(difference)
    result.checked["ledger line"] = entry.line


def _journal(folder: RunFolder, result: VerifyResult) -> list[dict[str, Any]]:
    path = folder.path / JOURNAL
    if not path.is_file():
        raise _Mismatch(f"{path}: missing")
    try:
        events = [entry.event for entry in read_journal(path)]
    except JournalError as exc:
        raise _Mismatch(str(exc)) from None
    except OSError as exc:
        raise _Mismatch(f"{path}: unreadable: {exc}") from None
    if not events:
        raise _Mismatch(f"{path}: empty; a run's journal opens with run_started")
    for index, event in enumerate(events, start=1):
        if event.get("seq") != index:
            raise _Mismatch(f"{path}:{index}: seq is {event.get('seq')!r}, expected {index}")
    result.checked["journal lines"] = len(events)
    return events


def _shape(folder: RunFolder, events: list[dict[str, Any]], result: VerifyResult
           ) -> dict[str, Any]:
    path = folder.path / JOURNAL
    first = events[0]
    if first.get("event") != JournalEvent.RUN_STARTED:
        raise _Mismatch(f"{path}:1: the journal opens with {first.get('event')!r}, "
                        "not run_started")
    closed = [i for i, e in enumerate(events, start=1) if e.get("event") == JournalEvent.RUN_CLOSED]
    if not closed:
        last = events[-1]
        raise _Mismatch(f"{path}: INCOMPLETE: no run_closed; the history ends at line "
                        f"{len(events)} ({last.get('event')}) — a faulted, interrupted or "
                        "truncated run")
    for line, event in enumerate(events[closed[0]:], start=closed[0] + 1):
        if event.get("event") not in AFTER_CLOSE:
            raise _Mismatch(f"{path}:{line}: {event.get('event')!r} after run_closed "
                            f"(line {closed[0]}); a closed run gains only report rebuilds")
    return first


def _inputs_and_identity(folder: RunFolder, started: dict[str, Any],
                         events: list[dict[str, Any]], result: VerifyResult) -> None:
    root = folder.path
    where = f"{JOURNAL}:1 run_started"
    try:
        manifest = folder.read_manifest()
    except (OSError, ValueError) as exc:
        raise _Mismatch(f"{root / 'manifest.json'}: unreadable: {exc}") from None
    if not isinstance(manifest, dict):
        raise _Mismatch(f"{root / 'manifest.json'}: not a JSON object")
    journaled_inputs = started.get("inputs")
    identity = started.get("identity")
    if journaled_inputs is None or identity is None:
        raise _Mismatch(f"{where}: records no input hashes or identity (a run from a gyrocal "
                        "older than the audit trail, or an edited journal)")
    inputs = manifest.get("inputs") or {}
    if set(inputs) != set(journaled_inputs):
        raise _Mismatch(f"{root / 'manifest.json'}: inputs {sorted(inputs)} differ from "
                        f"{sorted(journaled_inputs)} recorded in {where}")
    for role, digest in journaled_inputs.items():
        entry = inputs[role]
        _check_file(root / str(entry.get("copy", "")), digest, f"{where} inputs.{role}")
        if entry.get("sha256") != digest:
            raise _Mismatch(f"{root / 'manifest.json'}: inputs.{role}.sha256 differs from "
                            f"{where}")
    result.checked["input copies"] = len(journaled_inputs)
    _check_file(root / PLAN_RECORD, started.get("plan_sha256"), f"{where} plan_sha256")
    if manifest.get("plan_sha256") != started.get("plan_sha256"):
        raise _Mismatch(f"{root / 'manifest.json'}: plan_sha256 differs from {where}")
    result.checked["plan record"] = 1
    for key in IDENTITY_KEYS:
        if manifest.get(key) != identity.get(key):
            raise _Mismatch(f"{root / 'manifest.json'}: {key} is {manifest.get(key)!r}, "
                            f"{where} recorded {identity.get(key)!r}")
    result.checked["identity fields"] = len(IDENTITY_KEYS)
    _instrument_identities(root, manifest, events, result)


def _instrument_identities(root: Path, manifest: dict[str, Any], events: list[dict[str, Any]],
                           result: VerifyResult) -> None:
    """The manifest's instruments are the ones the journal's instrument_identified recorded."""
    journaled = identified_instruments(events)
    listed = manifest.get("instruments") or {}
    if not isinstance(listed, dict):
        raise _Mismatch(f"{root / 'manifest.json'}: instruments is not a JSON object")
    for role in sorted(set(listed) | set(journaled)):
        if listed.get(role) != journaled.get(role):
            raise _Mismatch(f"{root / 'manifest.json'}: instruments.{role} is "
                            f"{listed.get(role)!r}, the journal's instrument_identified "
                            f"recorded {journaled.get(role)!r}")
    result.checked["instrument identities"] = len(journaled)


def _set_aside_and_certificates(folder: RunFolder, events: list[dict[str, Any]],
                                result: VerifyResult) -> None:
    """Set-aside files and certificates: on disk with the hash their event recorded."""
    root = folder.path
    certificates: dict[str, tuple[int, dict[str, Any]]] = {}
    for line, event in enumerate(events, start=1):
        name = event.get("event")
        where = f"{JOURNAL}:{line} {name}"
        if name == JournalEvent.ORPHAN_SET_ASIDE:
            _check_file(root / str(event.get("moved_to", "")), event.get("sha256"), where)
            result.orphans.append(f"{event.get('path')} → {event.get('moved_to')} "
                                  f"({event.get('reason')})")
        elif name == JournalEvent.TORN_TAIL_SET_ASIDE:
            result.orphans.append(f"torn journal tail → {event.get('path')}")
        elif name == JournalEvent.CERTIFICATE_WRITTEN:
            certificates[str(event.get("path"))] = (line, event)
    torn = [(i, e) for i, e in enumerate(events, start=1) if e.get("event") == JournalEvent.TORN_TAIL_SET_ASIDE]
    if torn:
        line, event = torn[-1]
        _check_file(root / str(event.get("path", "")), event.get("torn_sha256"),
                    f"{JOURNAL}:{line} torn_tail_set_aside")
    for path, (line, event) in sorted(certificates.items()):
        if event.get("in_run_folder"):
            _check_file(root / path, event.get("sha256"), f"{JOURNAL}:{line} certificate_written")
        result.certificates.append(f"{event.get('number')}: {path} SHA-256 {event.get('sha256')}"
                                   + ("" if event.get("in_run_folder") else " (outside the run "
                                      "folder: not checked)"))
    result.checked["certificates"] = len(certificates)


def _nothing_unrecorded(folder: RunFolder, events: list[dict[str, Any]],
                        result: VerifyResult) -> None:
    """Every file in the run folder is one the history records (strays.py has the list)."""
    strays = unrecorded(folder.path, events, folder.read_manifest())
    if strays:
        first = strays[0]
        raise _Mismatch(f"{folder.path / first.path}: in the run folder but recorded by no "
                        f"journal event ({first.reason}; {len(strays)} such file(s)); "
                        f"`gyrocal resume {folder.path}` sets what a crash left aside")
    result.checked["files accounted for"] = len(files_on_disk(folder.path))


def _samples(folder: RunFolder, events: list[dict[str, Any]], result: VerifyResult) -> None:
    root = folder.path
    chunks = [(i, e) for i, e in enumerate(events, start=1) if e.get("event") == JournalEvent.CHUNK_WRITTEN]
    journaled: set[str] = set()
    for line, event in chunks:
        _check_file(root / str(event.get("path", "")), event.get("sha256"),
                    f"{JOURNAL}:{line} chunk_written")
        journaled.add(str(event.get("path")))
    on_disk = {str(p.relative_to(root)) for p in (root / SAMPLES).rglob("*") if p.is_file()}
    extra = sorted(on_disk - journaled)
    if extra:
        raise _Mismatch(f"{root / extra[0]}: on disk but not journaled "
                        f"({len(extra)} such file(s)); samples may not be added afterwards")
    for line, event in enumerate(events, start=1):
        if event.get("event") == JournalEvent.STEP_COMPLETED:
            missing = [c for c in event.get("chunks") or [] if c not in journaled]
            if missing:
                raise _Mismatch(f"{JOURNAL}:{line}: step {event.get('step_id')} lists chunk "
                                f"{missing[0]} that no chunk_written event recorded")
    result.checked["sample chunks"] = len(chunks)


def _report(folder: RunFolder, events: list[dict[str, Any]], result: VerifyResult,
            recompute: bool, key: Ed25519PublicKey | None) -> None:
    root = folder.path
    reports = [(i, e) for i, e in enumerate(events, start=1) if e.get("event") == JournalEvent.REPORT_WRITTEN]
    if not reports:
        raise _Mismatch(f"{root / 'report'}: no report_written event: the report was never "
                        "built; a closed run always has one")
    line, last = reports[-1]
    files = last.get("files") or {}
    for rel, digest in files.items():
        _check_file(root / rel, digest, f"{JOURNAL}:{line} report_written")
    present = {str(p.relative_to(root)) for p in (root / "report").rglob("*") if p.is_file()}
    certified = {str(e.get("path")) for e in events
                 if e.get("event") == JournalEvent.CERTIFICATE_WRITTEN and e.get("in_run_folder")}
    extra = sorted(present - set(files) - certified)
    if extra:
        raise _Mismatch(f"{root / extra[0]}: in report/ but not recorded by {JOURNAL}:{line} "
                        "report_written")
    result.checked["report files"] = len(files)
    results_path = root / "report/results.json"
    if "report/results.json" not in files:
        raise _Mismatch(f"{results_path}: not recorded by {JOURNAL}:{line} report_written")
    stored = _load_results(results_path)
    _report_signature(stored, results_path, events, line, key, result)
    if recompute:
        _recompute(folder, stored, results_path, result)


def _load_results(path: Path) -> dict[str, Any]:
    try:
        stored = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise _Mismatch(f"{path}: unreadable: {exc}") from None
    if not isinstance(stored, dict):
        raise _Mismatch(f"{path}: not a JSON object")
    return stored


def _report_signature(stored: dict[str, Any], path: Path, events: list[dict[str, Any]],
                      line: int, key: Ed25519PublicKey | None, result: VerifyResult) -> None:
    """The report's own signature: over the chain head its report_written chains to."""
    block = stored.get("signature")
    started_key = events[0].get("signing_key")
    if not isinstance(block, dict) or not block.get("signed"):
        if started_key or key is not None:
            raise _Mismatch(f"{path}: signature: the report is not signed, but "
                            + (f"run_started names signing key {started_key}" if started_key
                               else "--key was given"))
        return
    head = events[line - 1].get("prev_sha256")
    if block.get("chain_head") != head:
        raise _Mismatch(f"{path}: signature.chain_head {block.get('chain_head')} is not the "
                        f"head {head} that {JOURNAL}:{line} report_written chains to")
    if block.get("run_id") != events[0].get("run_id"):
        raise _Mismatch(f"{path}: signature.run_id {block.get('run_id')!r} is not the run's "
                        f"{events[0].get('run_id')!r}")
    unsigned = sha256_bytes(results_bytes({k: v for k, v in stored.items() if k != "signature"}))
    if block.get("results_sha256") != unsigned:
        raise _Mismatch(f"{path}: signature.results_sha256 does not match the report's numbers")
    if not report_signature_valid(block):
        raise _Mismatch(f"{path}: the report's signature does not verify")
    if key is not None and not report_signature_valid(block, key):
        raise _Mismatch(f"{path}: report signed by key {block.get('key_fingerprint')}, not by "
                        f"the given key {fingerprint(key)}: NOT AUTHENTIC")
    if block.get("key_fingerprint") != started_key:
        raise _Mismatch(f"{path}: report signed by key {block.get('key_fingerprint')}, but "
                        f"run_started names signing key {started_key}")
    result.checked["report signature"] = 1


def _recompute(folder: RunFolder, stored: dict[str, Any], results_path: Path,
               result: VerifyResult) -> None:
    """Step 5: the report's numbers recomputed from the samples with this gyrocal.

    What both the report and this gyrocal have must agree (a changed value fails). A key
    this gyrocal computes but the report lacks was added after the report was built (an
    older gyrocal wrote it): it cannot be compared, so it is named, not failed. A key the
    report has and this gyrocal does not compute fails: the report states a number that
    cannot be confirmed from the samples.
    """
    notes: list[str] = []
    computed = compute_results(read_run(folder.path, notes), notes)
    fresh = json.loads(json.dumps(finite_or_none(computed.to_json())))
    absent: list[str] = []
    for key in RECOMPUTED_KEYS:
        difference = _first_difference(stored.get(key, _ABSENT), fresh.get(key, _ABSENT),
                                       key, absent)
        if difference is not None:
            raise _Mismatch(f"{results_path}: {difference}: the report does not follow from "
                            "the samples")
    result.checked["numbers recomputed"] = len(RECOMPUTED_KEYS)
    result.not_in_report = absent


#: A key one side of the comparison does not have (unlike a key whose value is null).
_ABSENT = object()


def _first_difference(stored: Any, fresh: Any, where: str, absent: list[str]) -> str | None:
    """The first value the report and the recomputation disagree on, or None.

    Keys only the recomputation has are appended to ``absent`` (see :func:`_recompute`).
    """
    if stored is _ABSENT and fresh is not _ABSENT:
        absent.append(where)
        return None
    if fresh is _ABSENT:
        return None if stored is None else \
            f"{where} is {stored!r}, which this gyrocal does not compute"
    if isinstance(fresh, dict) and isinstance(stored, dict):
        for key in sorted(set(fresh) | set(stored)):
            found = _first_difference(stored.get(key, _ABSENT), fresh.get(key, _ABSENT),
                                      f"{where}.{key}", absent)
            if found:
                return found
        return None
    if isinstance(fresh, list) and isinstance(stored, list):
        if len(fresh) != len(stored):
            return f"{where} has {len(stored)} entries, recomputed {len(fresh)}"
        for index, (a, b) in enumerate(zip(stored, fresh, strict=True)):
            found = _first_difference(a, b, f"{where}[{index}]", absent)
            if found:
                return found
        return None
    both_numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       for v in (stored, fresh))
    if both_numbers:
        if math.isclose(float(stored), float(fresh), rel_tol=RECOMPUTE_RTOL, abs_tol=1e-300):
            return None
    elif stored == fresh:
        return None
    return f"{where} is {stored!r}, recomputed {fresh!r}"


def _seals(events: list[dict[str, Any]], key: Ed25519PublicKey | None, result: VerifyResult
           ) -> None:
    seals = [(i, e) for i, e in enumerate(events, start=1) if e.get("event") == SEAL_EVENT]
    started_key = events[0].get("signing_key")
    if not seals:
        if key is not None:
            raise _Mismatch(f"{JOURNAL}: not signed (no {SEAL_EVENT} event), but --key was given: "
                            "authenticity cannot be shown")
        if started_key:
            raise _Mismatch(f"{JOURNAL}: run_started names signing key {started_key} but no "
                            f"{SEAL_EVENT} event is left: the sealed tail was removed")
        result.authenticity = ("integrity only, not authenticity: the run is not signed "
                               "(the station has no signing key)")
        return
    last_line = seals[-1][0]
    if last_line != len(events):
        raise _Mismatch(f"{JOURNAL}:{last_line + 1}: lines {last_line + 1}–{len(events)} follow "
                        f"the last seal (line {last_line}) and are not signed")
    fingerprints = set()
    for line, seal in seals:
        if not seal_signature_valid(seal):
            raise _Mismatch(f"{JOURNAL}:{line}: the seal's signature does not verify: the "
                            "history before it was changed after it was signed")
        if key is not None and not seal_signature_valid(seal, key):
            raise _Mismatch(f"{JOURNAL}:{line}: sealed by key {seal.get('key_fingerprint')}, "
                            f"not by the given key {fingerprint(key)}: NOT AUTHENTIC")
        fingerprints.add(str(seal.get("key_fingerprint")))
    if started_key and fingerprints != {started_key}:
        raise _Mismatch(f"{JOURNAL}: sealed by {', '.join(sorted(fingerprints))}, but run_started "
                        f"names signing key {started_key}")
    result.checked["seals"] = len(seals)
    if key is not None:
        result.authenticity = (f"authentic: {len(seals)} seal(s) verified with the given key "
                               f"{fingerprint(key)}")
    else:
        result.authenticity = (f"integrity only, not authenticity: signed by key "
                               f"{', '.join(sorted(fingerprints))} (unverified; pass --key "
                               "station.pub to check it is the station's)")
