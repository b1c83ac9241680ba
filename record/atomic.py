"""Crash-safe file writes: temporary file, fsync, rename, fsync of the folder.

A kill -9 at any instant leaves either the old file or the complete new one,
never a half-written file under the final name.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from gyrocal.record.crash import at_atomic_write


def fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


#: Temporary files of atomic writes are named ``.NAME.XXXX.tmp`` beside their target; a kill
#: between write and rename leaves one behind (the next controller sets it aside).
TMP_PREFIX, TMP_SUFFIX = ".", ".tmp"

#: Run files (manifest, chunks, plan, report) are records a QA group reads: readable by the
#: group, written by the owner only. ``mkstemp`` alone would leave them 0600.
RECORD_MODE = 0o640


def write_atomic(path: Path, writer: Callable[[Path], None], mode: int = RECORD_MODE,
                 durable: bool = True) -> None:
    """Call ``writer(tmp_path)`` then move the result to ``path`` atomically.

    ``durable=False`` (a dry run's sample chunks: see :attr:`RunFolder.durable`) keeps the
    temporary file and the rename, so a kill -9 still leaves the old file or the whole new
    one (the page cache outlives the process), and skips the two fsyncs that only a power
    cut needs.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f"{TMP_PREFIX}{path.name}.", suffix=TMP_SUFFIX, dir=path.parent)
    os.fchmod(fd, mode)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        writer(tmp)
        if durable:
            with open(tmp, "rb") as handle:
                os.fsync(handle.fileno())
        at_atomic_write()
        os.replace(tmp, path)
        if durable:
            fsync_dir(path.parent)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: Path, data: bytes) -> None:
    write_atomic(path, lambda tmp: tmp.write_bytes(data))
