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
from tests.support.short_run import without_report_figures

pytestmark = pytest.mark.timeout(120)

#: The whole journal of the small plan fits (about 95 KB: a dry run's step_completed lines
#: carry the simulator state, ~10 KB each); one 8 s chunk at 2 kHz (~200 KB) does not.
LIMIT_BYTES = 140 * 1024


def _limited() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


@pytest.mark.slow
def test_no_room_to_write_is_a_fault_with_the_rig_safe_and_the_run_resumable(
        h: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    procedure = h.write_procedure(tmp_path)
    procedure.write_text(procedure.read_text().replace("sample_rate_hz: 250",
                                                       "sample_rate_hz: 2000"))
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
    without_report_figures(monkeypatch)      # the resume's record is the point, not its figures
    assert main(["resume", str(out)]) == EXIT_OK
    assert sorted(h.completed_ids(out)) == sorted(h.SMALL_PLAN)
    h.assert_chunks_intact(out)


def test_a_journal_line_that_does_not_fit_is_cut_off_whole(tmp_path: Path) -> None:
    """The kernel may take part of a line before the limit and refuse the rest: the
    journal cuts the part off again, so every line on disk is whole and chained."""
    path = tmp_path / "journal.jsonl"
    script = (
        "import sys\n"
        "from gyrocal.record.journal import Journal\n"
        f"journal = Journal({str(path)!r})\n"
        "try:\n"
        "    for i in range(1000):\n"
        "        journal.append('note', text='x' * 700)\n"
        "except OSError as exc:\n"
        "    print(journal.count, exc.errno)\n"
        "    sys.exit(0)\n"
        "sys.exit(1)\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          preexec_fn=_limited, timeout=60)
    assert proc.returncode == 0, proc.stderr
    count = int(proc.stdout.split()[0])
    assert LIMIT_BYTES // 1000 <= count < 1000     # ~850 bytes a line
    lines = list(read_journal(path))                 # whole, chained, nothing torn
    assert len(lines) == count
    assert path.stat().st_size < LIMIT_BYTES and path.read_bytes().endswith(b"\n")
