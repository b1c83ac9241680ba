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
    # "exiting" is printed once entry() has its code and raises SystemExit: from then on
    # the interpreter only waits on the thread (60 s), whatever the machine's load
    script = ("import threading, time, sys; from gyrocal.cli import entry; "
              "threading.Thread(target=time.sleep, args=(60,)).start(); "
              f"print('command', flush=True)\ntry:\n    entry(['status', {str(tmp_path / target)!r}])"
              "\nfinally:\n    print('exiting', flush=True)")
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "command"
    lines = []
    while (line := proc.stdout.readline()) and line.strip() != "exiting":
        lines.append(line)
    assert line.strip() == "exiting", (lines, proc.stderr.read())
    time.sleep(0.2)              # into the interpreter's exit, waiting on the thread
    started = time.monotonic()
    proc.send_signal(signum)
    rest, err = proc.communicate(timeout=60)
    out = "".join(lines) + rest
    assert time.monotonic() - started < 30           # at once, not after the thread's 60 s
    assert proc.returncode == expected, err
    assert "Traceback" not in err and "Exception ignored" not in err and \
        "KeyboardInterrupt" not in err, err
    assert ("state: done" in out) == (target == "run")
