"""The faults that end a run in the safe state (exit 3, resumable): one home for engine and executors."""

from __future__ import annotations


class RunFaultError(Exception):
    """A condition that ends the run in the safe state (exit code 3); the run is resumable."""


class SoakTimeoutError(RunFaultError):
    pass


class StepQualityError(RunFaultError):
    pass
