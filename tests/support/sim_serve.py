"""``gyrocal sim serve`` in its own process, for tests that drive a live station from outside."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from tests.support.fork_server import Forked, ForkServer

REPO = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def served_station(live: Path, station: str = "stations/sim.yaml",
                   env: dict[str, str] | None = None,
                   extra_args: tuple[str, ...] = (),
                   server: ForkServer | None = None) -> Iterator[Path]:
    """Start the simulators, wait for the live station file, stop them with Ctrl-C after.

    With ``server`` (the tests' warm fork server) ``gyrocal sim serve`` is forked from it:
    a process of its own all the same, reached through the same sockets and pty, stopped
    by the same Ctrl-C, without an interpreter start and the imports (~2.5 s of CPU)."""
    if server is not None:
        with _forked_serve(live, station, env, extra_args, server):
            yield live
        return
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyrocal", "sim", "serve", "--station", station,
         "--write-station", str(live), *extra_args],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 120   # an interpreter start on a loaded host
        while time.monotonic() < deadline and \
                "station file with these addresses" not in proc.stdout.readline():
            pass
        assert live.exists(), proc.stderr.read() if proc.poll() is not None else \
            "sim serve did not start"
        yield live
    finally:
        stop(proc)


@contextlib.contextmanager
def _forked_serve(live: Path, station: str, env: dict[str, str] | None,
                  extra_args: tuple[str, ...], server: ForkServer) -> Iterator[None]:
    out, err = live.with_name(f"{live.name}.serve.out"), live.with_name(f"{live.name}.serve.err")
    proc = server.start(["sim", "serve", "--station", station, "--write-station", str(live),
                         *extra_args], env or {}, err, stdout_path=out)
    try:
        deadline = time.monotonic() + 120
        while "station file with these addresses" not in (out.read_text() if out.exists()
                                                          else ""):
            assert proc.poll() is None and time.monotonic() < deadline, (
                f"sim serve did not start: {err.read_text() if err.exists() else ''}")
            time.sleep(0.02)
        assert live.exists(), out.read_text()
        yield
    finally:
        stop(proc)


def stop(proc: subprocess.Popen | Forked) -> None:
    """Ctrl-C, as an operator would; killed if it has not ended 60 s later."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
