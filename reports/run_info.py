"""Who, what, where and with what: results.json ``run`` and the provenance beside it, typed.

``run`` is taken from the ``run_started`` identity (signed) rather than the mutable
manifest where both exist; a report is built before the run closes, so the times a
certificate needs are those the steps were done.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from gyrocal.analysis.rate.dwell import SegmentDrift
from gyrocal.metrology.decision import IdentityCheck
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
class StationRecord:
    """results.json ``station``: the station file's name and where it is."""

    name: str | None
    file: str | None
    site: Mapping[str, Any] | None      # as plan.json gives it (latitude_deg…)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "file": self.file, "site": self.site}


@dataclass(frozen=True)
class InstrumentRecord:
    """One entry of results.json ``instruments``: the driver the run used, what the
    instrument reported, the identity the station declares, and what the decision rule
    found about it (metrology/decision.py), once judged."""

    driver: str | None
    address: str | None
    description: str | None
    make: str | None
    model: str | None
    serial: str | None
    calibration_due: str | None
    calibration_overdue: bool
    calibration_waiver: str | None
    calibration_certificate: str | None
    calibrated_by: str | None
    check: IdentityCheck | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"driver": self.driver, "address": self.address, "description": self.description,
               "make": self.make, "model": self.model, "serial": self.serial,
               "calibration_due": self.calibration_due,
               "calibration_overdue": self.calibration_overdue,
               "calibration_waiver": self.calibration_waiver,
               "calibration_certificate": self.calibration_certificate,
               "calibrated_by": self.calibrated_by}
        return out if self.check is None else out | self.check.to_json()


@dataclass(frozen=True)
class InputRecord:
    """One entry of results.json ``inputs``: an input file's copy in the run folder."""

    copy: str | None
    source: str | None
    sha256: str | None

    def to_json(self) -> dict[str, Any]:
        return {"copy": self.copy, "source": self.source, "sha256": self.sha256}


@dataclass(frozen=True)
class JournalSummary:
    """results.json ``journal``: the events a reader of the report must see, and counts."""

    events: tuple[Mapping[str, Any], ...]       # the shown events as journalled
    retries: int
    faults: int
    bad_steps: int
    chunks: int
    samples_sha256: str
    event_count: int
    first_wall_time: float | None
    last_wall_time: float | None

    def to_json(self) -> dict[str, Any]:
        return {"events": [dict(e) for e in self.events], "retries": self.retries,
                "faults": self.faults, "bad_steps": self.bad_steps, "chunks": self.chunks,
                "samples_sha256": self.samples_sha256, "event_count": self.event_count,
                "first_wall_time": self.first_wall_time, "last_wall_time": self.last_wall_time}


@dataclass(frozen=True)
class StepRecord:
    """One entry of results.json ``steps``: a logged step reduced to its mean."""

    step_id: str
    kind: str
    setpoint_c: float
    rate_dps: float
    output_mean: float
    n_used: int
    n_logged: int
    revolutions_used: float | None
    sensor_temp_c: float | None
    drift: SegmentDrift | None

    def to_json(self) -> dict[str, Any]:
        return {"step_id": self.step_id, "kind": self.kind, "setpoint_c": self.setpoint_c,
                "rate_dps": self.rate_dps, "output_mean": self.output_mean,
                "n_used": self.n_used, "n_logged": self.n_logged,
                "revolutions_used": self.revolutions_used, "sensor_temp_c": self.sensor_temp_c,
                "drift": None if self.drift is None else self.drift.to_json()}


@dataclass(frozen=True)
class Provenance:
    """Who, what, where and with what: ``run`` … ``steps``, in file order."""

    run: RunInfo
    procedure: Mapping[str, Any] | None     # plan.json's procedure record, as it is
    station: StationRecord
    instruments: Mapping[str, InstrumentRecord]
    inputs: Mapping[str, InputRecord]
    journal: JournalSummary
    steps: tuple[StepRecord, ...]

    def to_json(self) -> dict[str, Any]:
        return {"run": self.run.to_json(), "procedure": self.procedure,
                "station": self.station.to_json(),
                "instruments": {role: i.to_json() for role, i in self.instruments.items()},
                "inputs": {role: i.to_json() for role, i in self.inputs.items()},
                "journal": self.journal.to_json(),
                "steps": [s.to_json() for s in self.steps]}

    def judged(self, checks: Mapping[str, IdentityCheck]) -> Provenance:
        """The same record with each instrument's identity check beside it."""
        return replace(self, instruments={role: replace(i, check=checks.get(role))
                                          for role, i in self.instruments.items()})
