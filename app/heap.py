"""Keep a command's large numpy arrays on the C heap instead of fresh mmaps (glibc only).

glibc serves every allocation above ``M_MMAP_THRESHOLD`` (128 KiB, growing to at
most 32 MiB) with its own ``mmap`` and returns it with ``munmap`` on free. A
10 M-sample column is 80 MB, so each full-rate temporary of the discrepancy
workflow got pages the kernel had to fault in and zero afresh, and on the VMs
the labs and we run on a page fault is expensive. Raising the mmap and trim
thresholds past any array we make keeps freed blocks in the heap, where the next
array of the same size reuses the pages already faulted in; one arena
(``M_ARENA_MAX``) keeps the design evaluations' worker threads
(signatures.DesignBuilder) on that heap too: a thread's own arena cannot hold a
block above 64 MiB and would mmap it whatever the threshold. The arena limit
only holds for threads created after it, and pyarrow starts its own on import,
so the command line sets this before it imports the command (cli._lazy).

Measured on the overnight dry-run folder (10 M samples), `gyrocal discrepancy`
at load ~7–17 on 2 cores, the same tree with and without these settings:
system CPU 15.6 s → 4.7 s, minor page faults 512,000 → 73,000, user CPU
unchanged (19 s), peak RSS unchanged (3.2 GB). The results are the same bytes:
only where the memory comes from changes. With the residual and scan reuse
(analysis/discrepancy/context.py, periodic.py) beside it, at load 2.5: 28.4 s
wall, 15.6 s user + 12.6 s system, 517,000 faults before; 17.6 s wall, 14.9 s
user + 3.0 s system, 74,000 faults after (peak RSS 3.2 GB both).

On leaving, the thresholds go back to glibc's start-up values and the heap is
trimmed, so a process that runs the command in-process (tests, the demo) gets
its memory back (the single arena stays: glibc fixes the arena count once).
Elsewhere than glibc (musl, macOS) this does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import platform
from collections.abc import Iterator

#: mallopt parameters (glibc's malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
M_ARENA_MAX = -8
#: the largest value mallopt takes (its argument is a C int): above any array the workflow makes
HEAP_THRESHOLD_BYTES = 2**31 - 1
#: glibc's start-up values, restored on leaving
DEFAULT_THRESHOLD_BYTES = 128 * 1024


def _glibc() -> ctypes.CDLL | None:
    if platform.libc_ver()[0] != "glibc":
        return None
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        libc = ctypes.CDLL(name)
    except OSError:
        return None
    return libc if hasattr(libc, "mallopt") and hasattr(libc, "malloc_trim") else None


def _mallopt(libc: ctypes.CDLL, param: int, value: int) -> bool:
    return bool(libc.mallopt(ctypes.c_int(param), ctypes.c_int(value)))


@contextlib.contextmanager
def large_arrays_on_heap() -> Iterator[bool]:
    """Inside: big blocks come from (and return to) the heap; yields whether that was set."""
    libc = _glibc()
    done = libc is not None and all([_mallopt(libc, M_ARENA_MAX, 1),
                                     _mallopt(libc, M_MMAP_THRESHOLD, HEAP_THRESHOLD_BYTES),
                                     _mallopt(libc, M_TRIM_THRESHOLD, HEAP_THRESHOLD_BYTES)])
    try:
        yield done
    finally:
        if libc is not None:
            _mallopt(libc, M_MMAP_THRESHOLD, DEFAULT_THRESHOLD_BYTES)
            _mallopt(libc, M_TRIM_THRESHOLD, DEFAULT_THRESHOLD_BYTES)
            libc.malloc_trim(ctypes.c_size_t(0))
