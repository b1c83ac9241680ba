"""Who, what, where and with what: results.json ``run`` and the provenance beside it, typed.

``run`` is taken from the ``run_started`` identity (signed) rather than the mutable
manifest where both exist; a report is built before the run closes, so the times a
certificate needs are those the steps were done.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gyrocal.record.run_mode import RunMode

#: the keys of ``run`` that come from the run's recorded identity, in results.json order
IDENTITY_KEYS = ("run_id", "operator", "started_at", "mode", "seed", "speed", "software",
                 "station_name")


@dataclass(frozen=True)
class RunInfo:
    """results.json ``run``."""

    identity: Mapping[str, Any]     # IDENTITY_KEYS → the recorded value (mode as written)
    mode: RunMode | None
    plan_sha256: str | None
    ended_at: str | None
    state: str
    steps_done_at: str | None
    steps_started_at: str | None
    procedure_s: float | None       # the plan's ETA: on simulated time not the wall span

    @property
    def simulated(self) -> bool:
        return self.mode is RunMode.SIM

    def to_json(self) -> dict[str, Any]:
        out = {key: self.identity.get(key) for key in IDENTITY_KEYS}
        return out | {"plan_sha256": self.plan_sha256, "ended_at": self.ended_at,
                      "state": self.state, "simulated": self.simulated,
                      "steps_done_at": self.steps_done_at,
                      "steps_started_at": self.steps_started_at, "procedure_s": self.procedure_s}


def run_mode(value: object) -> RunMode | None:
    """The recorded mode; None when the record has none (or one this version does not know)."""
    try:
        return None if value is None else RunMode(value)
    except ValueError:
        return None


@dataclass(frozen=True)
class Provenance:
    """``run`` and the JSON-ready records beside it (procedure … steps), in file order."""

    run: RunInfo
    records: Mapping[str, Any]      # procedure, station, instruments, inputs, journal, steps

    def to_json(self) -> dict[str, Any]:
        return {"run": self.run.to_json(), **self.records}
