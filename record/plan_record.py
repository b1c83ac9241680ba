"""``plan.json``: what the report needs from the procedure and station, frozen at run start.

A report must be rebuildable by QA on another machine from the run folder
alone, long after the procedure file moved or the station changed. So the
run records, at start, the expanded steps (kind, setpoint, rate, settle,
revolutions…), the acceptance limits, the unit under test and the station's
site and instrument identities. Its SHA-256 is journalled like every input.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from gyrocal.models.gravity import STANDARD_GRAVITY_MPS2, local_gravity_g
from gyrocal.record.atomic import write_bytes_atomic
from gyrocal.record.run_folder import RunFolderError
from gyrocal.record.step_kind import StepKind

PLAN_RECORD = "plan.json"


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, (dt.date, Path)):
        return str(value)
    return value


def plan_record(procedure, plan) -> dict[str, Any]:
    station = procedure.station
    return {
        "version": 1,
        "procedure": {"name": procedure.name, "file": procedure.file,
                      "description": procedure.description},
        "unit_under_test": _plain(procedure.unit_under_test),
        "acceptance": _plain(procedure.acceptance),
        "sample_rate_hz": procedure.defaults.sample_rate_hz,
        "sanity": {"sf_tolerance_pct": procedure.data_quality.sf_tolerance_pct},
        "station": {
            "name": station.name,
            "file": station.file,
            "site": _plain(station.site),
            "uncertainty": station.uncertainty,
            # the magnetic steps' coil (constant and its uncertainty enter the sensitivity)
            "coil": _plain(station.coil) if station.coil is not None else None,
            "instruments": {
                "chamber": {"driver": station.chamber.driver, "address": station.chamber.address,
                            "identity": _plain(station.chamber.identity)},
                "table": {"driver": station.table.driver, "address": station.table.address,
                          "identity": _plain(station.table.identity)},
                "gyro": {"driver": station.gyro.driver, "address": station.gyro.port,
                         "identity": _plain(getattr(station.gyro, "identity", None))},
            },
        },
        "steps": [_plain(step) for step in plan.steps],
        # a multi-axis IMU calibration: which IMU axis each mounting puts up the table axis
        "mountings": [{"name": m.name, "up": m.up.label, "up_axis": m.up.up_axis,
                       "sign": m.up.sign, "face": m.face} for m in procedure.mountings],
        "mounting_order": procedure.mounting_order if procedure.mountings else None,
        "unit_under_test_axis": station.gyro.axis,
        "eta_s": plan.total_s,
    }


def write_plan_record(run_dir: Path, procedure, plan) -> Path:
    path = Path(run_dir) / PLAN_RECORD
    data = json.dumps(plan_record(procedure, plan), indent=2, allow_nan=False).encode() + b"\n"
    write_bytes_atomic(path, data)
    return path


# -- reading, typed ----------------------------------------------------------------------------


@dataclass(frozen=True)
class RecordedStep:
    """One plan step as plan.json keeps it (what an analysis needs of it)."""

    step_id: str
    kind: StepKind
    setpoint_c: float
    rate_dps: float
    temp_index: int
    duration_s: float
    revolutions: float | None = None
    mounting: str | None = None
    label: str | None = None
    base_rate_dps: float | None = None        # threshold steps (plan.PlanStep)
    confidence: float | None = None
    max_error_fraction: float | None = None
    linearity_tolerance_pct: float | None = None   # rate-limit steps
    fit_rates: int | None = None
    freq_hz: float | None = None                   # frequency-response steps
    amplitude_dps: float | None = None
    phase_at_hz: float | None = None
    field_t: float | None = None              # magnetic steps: the coil's set field, T
    angle_deg: float | None = None            # tilt steps: the table angle, deg
    band_dph: float | None = None             # turn-on steps: the stated band, deg/h
    off_s: float | None = None                # turn-on cycles: the cool-down, s
    expected_s: float | None = None           # the plan's expected duration (ETA, live page)

    @classmethod
    def of(cls, raw: dict[str, Any]) -> RecordedStep:
        return cls(str(raw["step_id"]), StepKind(raw["kind"]), float(raw["setpoint_c"]),
                   float(raw.get("rate_dps") or 0.0), int(raw.get("temp_index") or 0),
                   float(raw.get("duration_s") or 0.0), raw.get("revolutions"),
                   raw.get("mounting"), raw.get("label"), raw.get("base_rate_dps"),
                   raw.get("confidence"), raw.get("max_error_fraction"),
                   raw.get("linearity_tolerance_pct"), raw.get("fit_rates"),
                   raw.get("freq_hz"), raw.get("amplitude_dps"), raw.get("phase_at_hz"),
                   raw.get("field_t"), raw.get("angle_deg"), raw.get("band_dph"),
                   raw.get("off_s"), raw.get("expected_s"))


@dataclass(frozen=True)
class RecordedMounting:
    name: str
    up_axis: int
    sign: float
    face: str | None = None


@dataclass(frozen=True)
class PlanRecord:
    """plan.json, typed: the steps, the sample rate, the mountings, the station's site."""

    sample_rate_hz: float
    steps: tuple[RecordedStep, ...]
    mountings: tuple[RecordedMounting, ...]
    latitude_deg: float | None
    unit_under_test_axis: str
    height_m: float = 0.0                 # the station's height (local gravity)
    gravity_mps2: float | None = None     # a measured local gravity, if the station gives one
    #: the acceptance limits as the procedure gave them ({name, metric, max|min, unit, …})
    acceptance: tuple[dict[str, Any], ...] = ()
    #: the unit under test as the procedure declared it (serial, model, nominal SF…)
    unit_under_test: dict[str, Any] = field(default_factory=dict)
    procedure_name: str = ""
    #: the run's sanity bound on the scale factor against the nominal (data_quality)
    sf_tolerance_pct: float | None = None
    #: the JSON as written: the report's provenance copies parts of it verbatim (procedure,
    #: station site, instrument identities, uncertainty inputs), and only through here
    raw: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def of(cls, raw: dict[str, Any]) -> PlanRecord:
        station = raw.get("station") or {}
        site = station.get("site") or {}
        latitude = site.get("latitude_deg")
        sanity = raw.get("sanity") or {}
        tolerance = sanity.get("sf_tolerance_pct")
        return cls(
            sample_rate_hz=float(raw["sample_rate_hz"]),
            steps=tuple(RecordedStep.of(s) for s in raw.get("steps", [])),
            mountings=tuple(RecordedMounting(str(m["name"]), int(m["up_axis"]), float(m["sign"]),
                                             m.get("face"))
                            for m in raw.get("mountings") or []),
            latitude_deg=None if latitude is None else float(latitude),
            unit_under_test_axis=str(raw.get("unit_under_test_axis") or "x"),
            height_m=float(site.get("height_m") or 0.0),
            gravity_mps2=None if site.get("gravity_mps2") is None else float(site["gravity_mps2"]),
            acceptance=tuple(dict(a) for a in raw.get("acceptance") or []),
            unit_under_test=dict(raw.get("unit_under_test") or {}),
            procedure_name=str((raw.get("procedure") or {}).get("name") or ""),
            sf_tolerance_pct=None if tolerance is None else float(tolerance),
            raw=raw,
        )

    def step(self, step_id: str) -> RecordedStep | None:
        return next((s for s in self.steps if s.step_id == step_id), None)

    @property
    def kinds(self) -> dict[str, StepKind]:
        """step_id → kind (the Allan record is chosen among the holds)."""
        return {s.step_id: s.kind for s in self.steps}

    @property
    def gravity_g(self) -> float:
        """The station's local gravity in standard g (as the station computes it)."""
        if self.gravity_mps2 is not None:
            return self.gravity_mps2 / STANDARD_GRAVITY_MPS2
        return local_gravity_g(self.latitude_deg or 0.0, self.height_m)


class PlanRecordError(RunFolderError):
    """plan.json is missing or malformed (names the file); a bad-input error: exit 2."""


class PlanRecordMissing(PlanRecordError):
    """The run has no plan.json (yet: a run folder just created, or a damaged one)."""


def load_plan_record(run_dir: Path) -> PlanRecord:
    """plan.json of a run folder, typed: the one reader of the file.

    Raises :class:`PlanRecordMissing` when there is none, :class:`PlanRecordError`
    naming the file when it is not JSON or not a plan record.
    """
    path = Path(run_dir) / PLAN_RECORD
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PlanRecordMissing(f"{path}: missing; the run wrote no plan record") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PlanRecordError(f"{path}: cannot be read: {exc}") from None
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PlanRecordError(f"{path}: not valid JSON: {exc}") from None
    if not isinstance(raw, dict):
        raise PlanRecordError(f"{path}: not a plan record (a JSON {type(raw).__name__}, "
                              "expected an object)")
    try:
        return PlanRecord.of(raw)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise PlanRecordError(f"{path}: malformed plan record: {exc!r}") from None
