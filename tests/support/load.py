"""Machine load for the tests that must hold on a busy host: CPU hogs and an I/O hog, bounded.

A 2-core CI or lab machine shared with other jobs is where the real-time path
biased the scale factor (issue 28), so the tests reproduce that host on
purpose: ``cpu`` busy-loop processes and ``io`` processes rewriting a file in
a temporary folder with an fsync after every write (they compete for the disk
and the kernel's writeback as well). Every hog is a child process started
here and ended here by its own pid; each also stops by itself after ``max_s``,
so a test killed hard cannot leave one spinning.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

_CPU_HOG = """
import time
end = time.monotonic() + {max_s}
while time.monotonic() < end:
    pass
"""
_IO_HOG = """
import os, time
end = time.monotonic() + {max_s}
block = os.urandom(1 << 20)
while time.monotonic() < end:
    with open({path!r}, "wb") as f:
        for _ in range(32):
            f.write(block)
            f.flush()
            os.fsync(f.fileno())
"""


@contextlib.contextmanager
def machine_load(cpu: int = 2, io: int = 1, max_s: float = 120.0) -> Iterator[list[int]]:
    """Run ``cpu`` CPU hogs and ``io`` I/O hogs for the block; yields their pids."""
    procs: list[subprocess.Popen[bytes]] = []
    with tempfile.TemporaryDirectory(prefix="gyrocal-load-") as tmp:
        try:
            for _ in range(cpu):
                procs.append(subprocess.Popen(
                    [sys.executable, "-c", _CPU_HOG.format(max_s=float(max_s))]))
            for i in range(io):
                path = str(Path(tmp) / f"io-hog-{i}.bin")
                procs.append(subprocess.Popen(
                    [sys.executable, "-c", _IO_HOG.format(max_s=float(max_s), path=path)]))
            yield [p.pid for p in procs]
        finally:
            for proc in procs:
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
            for proc in procs:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=5.0)
