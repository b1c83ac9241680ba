"""The faults that end a run in the safe state (exit 3, resumable), by cause.

The base, :class:`~gyrocal.errors.RunFaultError`, lives with the exit codes in
``gyrocal/errors.py`` (one class for the engine, the executors and ``sim serve``);
it is imported here so the executors keep one import for the family.
"""

from __future__ import annotations

from gyrocal.errors import RunFaultError

__all__ = ["RunFaultError", "SoakTimeoutError", "StepQualityError"]


class SoakTimeoutError(RunFaultError):
    """The chamber did not settle within the soak's time limit."""


class StepQualityError(RunFaultError):
    """A logged step's samples failed their quality checks after every allowed attempt."""
