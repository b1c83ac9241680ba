"""No room to write in the middle of a run (issue 9, defect 3).

The adversarial pass filled the disk under 4 runs: each ended in a traceback
with exit 1 (the code for "acceptance failed"). Filling a real file system
needs a mount this test cannot count on, so the run process gets a file-size
limit instead (``ulimit -f``, RLIMIT_FSIZE, with SIGXFSZ ignored as a shell
does for a limited job): the first data chunk larger than the limit fails to
write with EFBIG - the same "no room" path as ENOSPC. The run must stop with
exit 3, no traceback, the rig confirmed safe, every journal line intact, and
``gyrocal resume`` must finish it once there is room.
"""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.journal import read_journal

pytestmark = pytest.mark.timeout(120)

LIMIT_BYTES = 48 * 1024     # the journal's lines fit; a 10 s chunk at 2 kHz does not


def _limited() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


def test_no_room_to_write_is_a_fault_with_the_rig_safe_and_the_run_resumable(
        h: Any, tmp_path: Path) -> None:
    procedure = h.write_procedure(tmp_path)
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "gyrocal", "run", str(procedure), "--sim", "--out", str(out),
         "--seed", "5"],
        cwd=h.REPO_ROOT, capture_output=True, text=True, preexec_fn=_limited, timeout=100)
    assert proc.returncode == EXIT_FAULT, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "no room to write" in proc.stderr and "File too large" in proc.stderr, proc.stderr
    assert f"gyrocal resume {out}" in proc.stderr
    list(read_journal(out / "journal.jsonl"))                   # the chain verifies
    events = h.events(out)
    safe = [e for e in events if e["event"] == "safe_state"]
    assert safe and safe[-1]["confirmed"] == {"table": True, "chamber": True}
    assert h.manifest(out)["state"] == "faulted"
    assert main(["resume", str(out)]) == EXIT_OK
    assert sorted(h.completed_ids(out)) == sorted(h.SMALL_PLAN)
    h.assert_chunks_intact(out)
