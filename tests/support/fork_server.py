"""A warm process that forks ``gyrocal`` commands on request (tests that run many short runs).

A test that kills a run at each of ~60 boundaries cannot pay an interpreter
start and the imports per run, and it cannot fork itself either: once this
process has run the compiled Allan kernel, GNU OpenMP refuses to work in a
forked child ("fork() called from a process already using GNU OpenMP"). So a
fresh interpreter imports the package, never computes anything, and forks one
child per request; each child runs ``gyrocal.cli.main`` with the given
environment, its stderr in a file, and the server answers with the child's
wait status.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

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
from gyrocal.cli import main
for line in sys.stdin:
    request = json.loads(line)
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
            code = main(request["argv"])
        except BaseException:
            import traceback
            traceback.print_exc()
            code = 98
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    print(json.dumps({"status": status}), flush=True)
"""


class ForkServer:
    """``run(argv, env, stderr_path)`` → the wait status of a forked ``gyrocal`` command."""

    def __init__(self, cwd: Path) -> None:
        self._proc = subprocess.Popen([sys.executable, "-c", _SERVER], cwd=cwd, text=True,
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    def run(self, argv: list[str], env: dict[str, str], stderr_path: Path) -> int:
        assert self._proc.stdin is not None and self._proc.stdout is not None
        self._proc.stdin.write(json.dumps({"argv": argv, "env": env,
                                           "stderr": str(stderr_path)}) + "\n")
        self._proc.stdin.flush()
        answer = self._proc.stdout.readline()
        assert answer, "the fork server died"
        return int(json.loads(answer)["status"])

    def close(self) -> None:
        if self._proc.stdin is not None:
            self._proc.stdin.close()
        self._proc.wait(timeout=30)

    def __enter__(self) -> ForkServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
