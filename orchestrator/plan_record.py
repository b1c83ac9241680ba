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
from enum import Enum
from pathlib import Path
from typing import Any

from gyrocal.orchestrator.atomic import write_bytes_atomic

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
        "station": {
            "name": station.name,
            "file": station.file,
            "site": _plain(station.site),
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


def read_plan_record(run_dir: Path) -> dict[str, Any]:
    return json.loads((Path(run_dir) / PLAN_RECORD).read_text())
