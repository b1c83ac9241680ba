"""The ``table_interference`` block of results.json: each drive-powered/drive-off pair compared.

A ``table_interference`` test plans two steps, ``….interference.powered``
(a static, drive on at zero rate) and ``….interference.off`` (drive off,
interlock open); this reads both records' gyro column (converted to deg/h
with the nominal scale factor), and compares them (``interference.py``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from gyrocal.analysis.environment.interference import compare
from gyrocal.models.rate_units import output_to_dph
from gyrocal.record.logged_steps import completed_attempts
from gyrocal.record.plan_record import PlanRecord
from gyrocal.record.step_kind import StepKind


def _gyro(run_dir: Path, event: dict[str, Any]) -> np.ndarray:
    parts = []
    for rel in event["chunks"]:
        table = pq.read_table(Path(run_dir) / rel, columns=["gyro", "status"])
        good = table.column("status").to_numpy() == 0
        parts.append(table.column("gyro").to_numpy()[good])
    return np.concatenate(parts)


def interference_section(run_dir: Path, plan: dict[str, Any], events: list[dict[str, Any]],
                         nominal_sf: float, notes: list[str]) -> list[dict[str, Any]] | None:
    """One entry per compared pair, or None when the plan has no drive-off step."""
    record = PlanRecord.of(plan)
    done = completed_attempts(events)
    out = []
    for step in record.steps:
        if step.kind != StepKind.DRIVE_OFF:
            continue
        powered_id = step.step_id.removesuffix(".off") + ".powered"
        if step.step_id not in done or powered_id not in done:
            notes.append(f"table interference: {step.step_id} or {powered_id} not completed")
            continue
        powered = output_to_dph(_gyro(run_dir, done[powered_id]), nominal_sf)
        off = output_to_dph(_gyro(run_dir, done[step.step_id]), nominal_sf)
        try:
            result = compare(np.asarray(powered), np.asarray(off), record.sample_rate_hz)
        except ValueError as exc:
            notes.append(f"table interference {step.step_id}: {exc}")
            continue
        out.append({"powered_step": powered_id, "off_step": step.step_id,
                    "setpoint_c": step.setpoint_c, **result.to_json()})
    return out or None
