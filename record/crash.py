"""Rehearsal hook: make this process kill itself (SIGKILL) at a chosen record boundary.

Crash consistency is a claim about *every* boundary between two records,
not about a random instant, so the test that backs it needs to stop the
process exactly there. ``GYROCAL_CRASH_AT`` names the boundary:

- ``before:K`` — right before journal line K is written (whatever files were
  written for it, a chunk or a report, are on disk; the line is not);
- ``after:K`` — right after journal line K is written and fsynced;
- ``tmp:N`` — inside the N-th atomic write of this process, when its
  temporary file is complete and not yet renamed.

Unset (always, outside rehearsals) it costs one dictionary lookup per
record. SIGKILL, not an exception: nothing of the process may run after it,
exactly as after a power cut's software half. ``GYROCAL_CRASH_SIGNAL``
(``SIGINT``, ``SIGTERM``) sends that signal instead, at the same boundary:
how the signal tests reach every phase of a run deterministically.
"""

from __future__ import annotations

import os
import signal

CRASH_AT_ENV = "GYROCAL_CRASH_AT"
CRASH_SIGNAL_ENV = "GYROCAL_CRASH_SIGNAL"

_atomic_writes = 0


def _target() -> tuple[str, int] | None:
    spec = os.environ.get(CRASH_AT_ENV)
    if not spec:
        return None
    where, _, number = spec.partition(":")
    try:
        return where, int(number)
    except ValueError:
        return None


def _die() -> None:
    name = os.environ.get(CRASH_SIGNAL_ENV) or "SIGKILL"
    os.kill(os.getpid(), getattr(signal, name, signal.SIGKILL))


def at_journal_line(when: str, seq: int) -> None:
    """Called by the journal ``before`` writing and ``after`` fsyncing line ``seq``."""
    target = _target()
    if target is not None and target == (when, seq):
        _die()


def at_atomic_write() -> None:
    """Called by an atomic write once its temporary file is complete, before the rename."""
    global _atomic_writes
    target = _target()
    if target is None or target[0] != "tmp":
        return
    _atomic_writes += 1
    if _atomic_writes == target[1]:
        _die()
