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
            os.dup2(devnull, 1)
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
        return self.start(argv, env, stderr_path, figures=figures).wait()

    def start(self, argv: list[str], env: dict[str, str], stderr_path: Path, *,
              figures: bool = True) -> Forked:
        """The command forked and left running (a test that signals it from outside)."""
        answer = self._ask({"argv": argv, "env": env, "figures": figures,
                            "stderr": str(stderr_path)})
        return Forked(self, int(answer["pid"]), stderr_path)

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
    """A command the server forked: its pid (to signal), its end (``poll``, ``wait``)."""

    def __init__(self, server: ForkServer, pid: int, stderr_path: Path) -> None:
        self._server = server
        self.pid = pid
        self.stderr_path = stderr_path

    def poll(self) -> int | None:
        """Its wait status if it has ended, else None."""
        return self._server._wait(self.pid, block=False)

    def wait(self, timeout_s: float | None = None) -> int:
        """Its wait status; killed (SIGKILL) if still running after ``timeout_s``."""
        if timeout_s is not None:
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline and self.poll() is None:
                time.sleep(0.05)
            if self.poll() is None:
                os.kill(self.pid, signal.SIGKILL)
        return int(self._server._wait(self.pid, block=True))

    def returncode(self) -> int:
        """Its exit code (``-N`` when signal N ended it), after it has ended."""
        return os.waitstatus_to_exitcode(self.wait())
