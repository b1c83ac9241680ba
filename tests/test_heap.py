"""app/heap.py: inside ``large_arrays_on_heap`` a freed 80 MB array's pages are reused, not faulted anew.

The discrepancy command's system time was mostly the kernel faulting in fresh
mmaps for each full-rate temporary; the check here is that very mechanism,
counted in minor page faults (resource.getrusage), not a timing.
"""

from __future__ import annotations

import platform
import resource

import numpy as np
import pytest

from gyrocal.app.heap import large_arrays_on_heap

N = 10_000_000   # an overnight log's samples: 80 MB of float64


def _faults_of_second_array() -> int:
    """Minor faults while filling an array of N floats right after one was freed."""
    first = np.ones(N)
    del first
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    second = np.ones(N)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    del second
    return faults


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_freed_array_pages_are_reused_inside_and_returned_after():
    outside = _faults_of_second_array()
    with large_arrays_on_heap() as on_heap:
        assert on_heap
        inside = _faults_of_second_array()
    after = _faults_of_second_array()
    # outside: a fresh mmap, 80 MB faulted in (4 KiB pages, or 2 MiB ones where the
    # kernel has them: at least 40 faults); inside: the freed block's pages again
    assert outside >= 40
    assert inside < 10 < outside
    # leaving restores the mmap threshold: a big array is its own mapping again
    assert after >= 40
