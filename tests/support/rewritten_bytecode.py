"""Write pytest's assertion-rewritten bytecode of the test modules once, before the workers start.

pytest rewrites the ``assert`` statements of every test module and conftest.py it
imports and caches the result in ``__pycache__`` (``*-pytest-<version>.pyc``), but
not where PYTHONDONTWRITEBYTECODE is set: there every process that collects the
suite parses and rewrites all ~190 modules again. Under ``make test`` that is each
of the four xdist workers, ~4 s of CPU each (measured, the suite collected in one
process: 8.9 s CPU rewriting, 4.8 s reading the cache). pytest reads a cached file
whether or not it may write one, so ``make test`` runs this first, as it compiles the
package with compileall: the same rewrite, done once, in parallel.

The rewriting is pytest's own (``_pytest.assertion.rewrite``: the function that
reads and rewrites a module and the one that writes its cache). Those are private:
if a pytest release changes them, this says so and writes nothing, and the suite
rewrites as before; nothing else depends on it. A stale or foreign cached file is
never used: pytest checks the source's hash on reading (or its mtime and size, by
release).

Usage: python tests/support/rewritten_bytecode.py DIR...   (exit 0 in every case)
"""

from __future__ import annotations

import os
import sys
from concurrent.futures import ProcessPoolExecutor
from fnmatch import fnmatch
from pathlib import Path

#: pytest's default ``python_files`` (pyproject sets none) and conftest.py, always rewritten
PATTERNS = ("test_*.py", "*_test.py", "conftest.py")


class _Quiet:
    """What pytest's cache writer takes to trace a failed write: nothing to trace here."""

    def trace(self, *_: object) -> None:
        return None


def rewrite_one(path: str) -> str | None:
    """Rewrite ``path`` and write its cached bytecode; the reason when it could not."""
    try:
        from _pytest.assertion import rewrite  # lazy: in the pool's processes only

        cache = Path(path).parent / "__pycache__"
        cache.mkdir(exist_ok=True)
        pyc = cache / (Path(path).name[:-3] + rewrite.PYC_TAIL)
        source_key, code = rewrite._rewrite_test(Path(path), None)
        rewrite._write_pyc(_Quiet(), code, source_key, pyc)
    except (ImportError, AttributeError, TypeError, OSError, SyntaxError) as error:
        return f"{path}: {type(error).__name__}: {error}"
    return None


def modules(folders: list[str]) -> list[str]:
    """Every file under ``folders`` that pytest would rewrite on import, by its absolute
    path (pytest compiles a module under that name: it is the code's file name)."""
    found = []
    for folder in folders:
        for root, dirs, files in os.walk(folder):
            dirs[:] = [d for d in dirs if d != "__pycache__" and not d.startswith(".")]
            found += [os.path.abspath(os.path.join(root, name)) for name in files
                      if any(fnmatch(name, pattern) for pattern in PATTERNS)]
    return sorted(found)


def main(folders: list[str]) -> int:
    paths = modules(folders)
    with ProcessPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        failures = [reason for reason in pool.map(rewrite_one, paths, chunksize=8) if reason]
    if failures:
        print(f"rewritten_bytecode: {len(failures)} of {len(paths)} module(s) left to pytest "
              f"(first: {failures[0]})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or ["tests"]))
