"""A warm process that forks ``gyrocal`` commands on request (tests that run many short runs).

A test that kills a run at each of ~60 boundaries cannot pay an interpreter
start and the imports per run, and it cannot fork itself either: once this
process has run the compiled Allan kernel, GNU OpenMP refuses to work in a
forked child ("fork() called from a process already using GNU OpenMP"). So a
fresh interpreter imports the package, never computes anything, and forks one
child per request; each child runs ``gyrocal.cli.main`` with the given
environment, its stderr in a file. The server answers with the child's pid,
and, asked, with its wait status (``run``: both at once; ``start``: the pid
now, for a test that signals the child from outside, the status later).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

_SERVER = r"""
import json, os, sys
import gyrocal.cli, gyrocal.app.run_commands, gyrocal.app.demo, gyrocal.orchestrator.engine  # noqa: warm
import gyrocal.instruments.sim.station_sim, gyrocal.reports.build  # noqa: warm
# what a run imports on its way (drivers, chunk writer, report page and figures): imported
# here once instead of in every child, about half of a child's CPU time (0.9 of 1.8 s)
import gyrocal.instruments.gyro.stim300, gyrocal.instruments.table.acutrol  # noqa: warm
import gyrocal.reports.html_report, gyrocal.reports.plots  # noqa: warm
import matplotlib.backends.backend_agg, PIL.PngImagePlugin, numba  # noqa: warm
import pyarrow.dataset, pyarrow.parquet, pyvisa_py.tcpip, pandas  # noqa: warm
# what every child did first, once here: the simulated gyro's compiled recursion loaded
# from numba's cache (~0.22 s of a child's CPU; single-threaded code, no OpenMP, so the
# children may still fork) and the report page's template compiled
import gyrocal.models.recursion  # noqa: warm
gyrocal.models.recursion.warm_up()
gyrocal.reports.html_report._template()
NO_FIGURES = gyrocal.reports.plots.all_plots({})
from gyrocal.cli import main
ended = {}
for line in sys.stdin:
    request = json.loads(line)
    if "wait" in request:      # {"wait": pid, "block": bool} -> {"status": its wait status or null}
        pid = request["wait"]
        if pid not in ended:
            done, status = os.waitpid(pid, 0 if request["block"] else os.WNOHANG)
            if done:
                ended[pid] = status
        print(json.dumps({"status": ended.get(pid)}), flush=True)
        continue
    pid = os.fork()
    if pid == 0:
        code = 99
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            err = os.open(request["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(devnull, 0)
            os.dup2(os.open(request["stdout"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
                    if request["stdout"] else devnull, 1)
            os.dup2(err, 2)
            os.environ.update(request["env"])
            if not request["figures"]:       # as tests/support/short_run.without_report_figures
                gyrocal.reports.html_report.all_plots = lambda results: dict(NO_FIGURES)
            code = main(request["argv"])
        except BaseException:
            import traceback
            traceback.print_exc()
            code = 98
        finally:
            os._exit(code)
    print(json.dumps({"pid": pid}), flush=True)
"""


class ForkServer:
    """``run(argv, env, stderr_path)`` → the wait status of a forked ``gyrocal`` command."""

    def __init__(self, cwd: Path) -> None:
        self._proc = subprocess.Popen([sys.executable, "-c", _SERVER], cwd=cwd, text=True,
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    def run(self, argv: list[str], env: dict[str, str], stderr_path: Path, *,
            figures: bool = True) -> int:
        """``figures=False``: the child's report page gets no figures, as
        ``without_report_figures`` does in the test's own process (for sweeps whose
        killed runs are checked for their records, never for the figures)."""
        forked = self.start(argv, env, stderr_path, figures=figures)
        forked.wait()
        assert forked.status is not None
        return forked.status

    def start(self, argv: list[str], env: dict[str, str], stderr_path: Path, *,
              figures: bool = True, stdout_path: Path | None = None) -> Forked:
        """The command forked and left running (a test that signals it from outside);
        its stdout in ``stdout_path`` if given, else discarded."""
        # the test's environment as a subprocess would inherit it, then ``env``
        answer = self._ask({"argv": argv, "env": {**os.environ, **env}, "figures": figures,
                            "stderr": str(stderr_path),
                            "stdout": str(stdout_path) if stdout_path else None})
        return Forked(self, int(answer["pid"]), stderr_path, stdout_path)

    def _wait(self, pid: int, block: bool) -> int | None:
        return self._ask({"wait": pid, "block": block})["status"]

    def _ask(self, request: dict[str, Any]) -> dict[str, Any]:
        assert self._proc.stdin is not None and self._proc.stdout is not None
        self._proc.stdin.write(json.dumps(request) + "\n")
        self._proc.stdin.flush()
        answer = self._proc.stdout.readline()
        assert answer, "the fork server died"
        return json.loads(answer)

    def close(self) -> None:
        if self._proc.stdin is not None:
            self._proc.stdin.close()
        self._proc.wait(timeout=30)

    def __enter__(self) -> ForkServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Forked:
    """A command the server forked, used as a ``subprocess.Popen`` of it is: ``pid`` (to
    signal), ``poll``, ``wait``, ``communicate`` (its stdout and stderr files' text),
    ``returncode``, ``send_signal``, ``kill``."""

    def __init__(self, server: ForkServer, pid: int, stderr_path: Path,
                 stdout_path: Path | None) -> None:
        self._server = server
        self.pid = pid
        self.stderr_path = stderr_path
        self.stdout_path = stdout_path
        self.status: int | None = None      # its wait status, once it has ended

    @property
    def returncode(self) -> int | None:
        """Its exit code (``-N`` when signal N ended it), None while it runs."""
        return None if self.status is None else os.waitstatus_to_exitcode(self.status)

    def poll(self) -> int | None:
        if self.status is None:
            self.status = self._server._wait(self.pid, block=False)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Its exit code once it has ended (``subprocess.TimeoutExpired`` after ``timeout``)."""
        if timeout is not None:
            deadline = time.monotonic() + timeout
            while self.poll() is None:
                if time.monotonic() > deadline:
                    raise subprocess.TimeoutExpired(f"forked {self.pid}", timeout)
                time.sleep(0.02)
        if self.status is None:
            self.status = int(self._server._wait(self.pid, block=True))
        return int(self.returncode)

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        return (self.stdout_path.read_text() if self.stdout_path else "",
                self.stderr_path.read_text())

    def send_signal(self, signum: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, signum)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)
