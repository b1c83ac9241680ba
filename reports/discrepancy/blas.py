"""Run the workflow's linear algebra on one BLAS thread.

The workflow's matrices are a few thousand rows: OpenBLAS gains little from
threads there, and on a shared 2-core machine its spinning threads collide
with other processes. Measured on the project machine under load: one
discrepancy analysis of a 1-hour log took 24 s with OpenBLAS threads and
1.8 s with one thread. numpy and scipy each ship their own OpenBLAS; both are
set through their exported ``*_set_num_threads`` and restored afterwards. If
the libraries cannot be found (another BLAS), nothing is changed.
"""

from __future__ import annotations

import ctypes
from collections.abc import Iterator
from contextlib import contextmanager

_PAIRS = (
    ("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
    ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
    ("openblas_set_num_threads", "openblas_get_num_threads"),
)


def _openblas_controls() -> list[tuple[object, object]]:
    try:
        with open("/proc/self/maps", encoding="utf-8") as handle:
            paths = {line.split()[-1] for line in handle if "openblas" in line.lower() and "/" in line}
    except OSError:
        return []
    controls = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for setter, getter in _PAIRS:
            if hasattr(lib, setter) and hasattr(lib, getter):
                controls.append((getattr(lib, setter), getattr(lib, getter)))
                break
    return controls


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Within the block, numpy's and scipy's OpenBLAS use one thread."""
    import numpy  # noqa: F401 - make sure the libraries are loaded before looking for them
    import scipy.linalg  # noqa: F401

    controls = _openblas_controls()
    previous = []
    for setter, getter in controls:
        previous.append(int(getter()))
        setter(1)
    try:
        yield
    finally:
        for (setter, _), count in zip(controls, previous, strict=True):
            setter(count)
