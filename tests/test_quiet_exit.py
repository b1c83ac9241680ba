"""A Ctrl-C while the interpreter shuts down is quiet (issue 28).

Measured before: a signal that arrived after the command had its exit code,
while Python joined threads at exit, printed "Exception ignored in: <module
'threading'> … KeyboardInterrupt" with a traceback. Here a non-daemon thread
holds the interpreter's exit open for seconds (as a slow teardown would), the
signal arrives in that window, and the process ends at once, quietly, with
the command's own exit code.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("target, expected", [("run", EXIT_OK), ("missing", EXIT_BAD_INPUT)])
def test_a_signal_during_interpreter_exit_ends_quietly_with_the_commands_code(
        tmp_path: Path, signum: int, target: str, expected: int) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "manifest.json").write_text(json.dumps({"run_id": "R1", "state": "done"}))
    script = ("import threading, time, sys; from gyrocal.cli import entry; "
              "threading.Thread(target=time.sleep, args=(20,)).start(); "
              f"print('command', flush=True); entry(['status', {str(tmp_path / target)!r}])")
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "command"
    time.sleep(2.0)              # the command is done; the interpreter waits on the thread
    started = time.monotonic()
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=15)
    assert time.monotonic() - started < 5            # at once, not after the thread's 20 s
    assert proc.returncode == expected, err
    assert "Traceback" not in err and "Exception ignored" not in err and \
        "KeyboardInterrupt" not in err, err
    assert ("state: done" in out) == (target == "run")
