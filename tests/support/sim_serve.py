"""``gyrocal sim serve`` in its own process, for tests that drive a live station from outside."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def served_station(live: Path, station: str = "stations/sim.yaml",
                   env: dict[str, str] | None = None,
                   extra_args: tuple[str, ...] = ()) -> Iterator[Path]:
    """Start the simulators, wait for the live station file, stop them with Ctrl-C after."""
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


def stop(proc: subprocess.Popen) -> None:
    """Ctrl-C, as an operator would; killed if it has not ended 60 s later."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
