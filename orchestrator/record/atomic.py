"""Crash-safe file writes: temporary file, fsync, rename, fsync of the folder.

A kill -9 at any instant leaves either the old file or the complete new one,
never a half-written file under the final name.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


#: Run files (manifest, chunks, plan, report) are records a QA group reads: readable by the
#: group, written by the owner only. ``mkstemp`` alone would leave them 0600.
RECORD_MODE = 0o640


def write_atomic(path: Path, writer: Callable[[Path], None], mode: int = RECORD_MODE) -> None:
    """Call ``writer(tmp_path)`` then move the result to ``path`` atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.fchmod(fd, mode)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        writer(tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: Path, data: bytes) -> None:
    write_atomic(path, lambda tmp: tmp.write_bytes(data))
