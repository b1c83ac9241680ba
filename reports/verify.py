"""``gyrocal verify``: recompute every hash a run folder records, stop at the first mismatch.

An auditor must be able to show that the report, the samples behind it and
the inputs it was run with are the ones the run produced. The chain is:
the journal's own hash chain; the chunks it lists (chunk_written events);
the input copies against the manifest; plan.json against the manifest's
plan_sha256; the report files against the last report_written event.
The manifest itself is mutable run state (state, pid, resumes) and carries
no hash of its own; what matters in it is cross-checked through the files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gyrocal.orchestrator.journal import JournalError, read_journal, sha256_file
from gyrocal.orchestrator.plan_record import PLAN_RECORD
from gyrocal.orchestrator.run_folder import JOURNAL, RunFolder


@dataclass
class VerifyResult:
    """``failure`` names the first file that does not match (None when all do)."""

    run_dir: Path
    failure: str | None = None
    checked: dict[str, int] = field(default_factory=dict)
    unchecked: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.failure is None

    def summary(self) -> str:
        counts = ", ".join(f"{n} {what}" for what, n in self.checked.items())
        extra = f" (not checked: {'; '.join(self.unchecked)})" if self.unchecked else ""
        return f"{self.run_dir}: OK — every hash matches: {counts}{extra}"


class _Mismatch(Exception):
    pass


def _check_file(path: Path, expected: str | None, what: str) -> None:
    if not path.is_file():
        raise _Mismatch(f"{path}: missing ({what})")
    if expected is None:
        raise _Mismatch(f"{path}: no recorded SHA-256 to check it against ({what})")
    actual = sha256_file(path)
    if actual != expected:
        raise _Mismatch(f"{path}: SHA-256 {actual} does not match {expected} recorded in {what}")


def verify_run_folder(run_dir: str | Path) -> VerifyResult:
    """Check every recorded hash; raises RunFolderError when this is not a run folder."""
    folder = RunFolder.open(Path(run_dir))
    result = VerifyResult(folder.path)
    try:
        _verify(folder, result)
    except _Mismatch as exc:
        result.failure = str(exc)
    return result


def _verify(folder: RunFolder, result: VerifyResult) -> None:
    root = folder.path
    journal_path = root / JOURNAL
    if not journal_path.is_file():
        raise _Mismatch(f"{journal_path}: missing")
    try:
        events = [entry.event for entry in read_journal(journal_path)]
    except JournalError as exc:
        raise _Mismatch(str(exc)) from None
    result.checked["journal lines"] = len(events)

    chunks = [e for e in events if e.get("event") == "chunk_written"]
    for event in chunks:
        _check_file(root / event["path"], event.get("sha256"),
                    f"{JOURNAL} event #{event.get('seq')} chunk_written")
    result.checked["sample chunks"] = len(chunks)

    manifest = folder.read_manifest()
    inputs = manifest.get("inputs") or {}
    for role, entry in inputs.items():
        _check_file(root / entry["copy"], entry.get("sha256"), f"manifest.json inputs.{role}")
    result.checked["input copies"] = len(inputs)

    if (root / PLAN_RECORD).exists() or manifest.get("plan_sha256"):
        _check_file(root / PLAN_RECORD, manifest.get("plan_sha256"), "manifest.json plan_sha256")
        result.checked["plan record"] = 1

    reports = [e for e in events if e.get("event") == "report_written"]
    if reports:
        files = reports[-1].get("files") or {}
        for rel, digest in files.items():
            _check_file(root / rel, digest,
                        f"{JOURNAL} event #{reports[-1].get('seq')} report_written")
        result.checked["report files"] = len(files)
    else:
        result.unchecked.append("no report_written event: the report was never built")
