"""The ``table_interference`` block of results.json: each drive-powered/drive-off pair compared.

A ``table_interference`` test plans two steps, ``….interference.powered``
(a static, drive on at zero rate) and ``….interference.off`` (drive off,
interlock open); this reads both records' gyro column (converted to deg/h
with the nominal scale factor), and compares them (``interference.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.analysis.environment.interference import InterferenceResult, compare
from gyrocal.models.rate_units import output_to_dph
from gyrocal.record.plan_record import PlanRecord
from gyrocal.record.samples import RunSamples
from gyrocal.record.step_kind import StepKind


@dataclass(frozen=True)
class InterferenceEntry:
    """One drive-powered/drive-off pair compared: an entry of results.json
    ``table_interference``."""

    powered_step: str
    off_step: str
    setpoint_c: float
    result: InterferenceResult

    def to_json(self) -> dict[str, Any]:
        return {"powered_step": self.powered_step, "off_step": self.off_step,
                "setpoint_c": self.setpoint_c, **self.result.to_json()}


def interference_section(run_dir: Path, record: PlanRecord, events: list[dict[str, Any]],
                         nominal_sf: float, notes: list[str]
                         ) -> tuple[InterferenceEntry, ...] | None:
    """One entry per compared pair, or None when the plan has no drive-off step."""
    done = RunSamples(run_dir, events)
    out = []
    for step in record.steps:
        if step.kind != StepKind.DRIVE_OFF:
            continue
        powered_id = step.step_id.removesuffix(".off") + ".powered"
        if step.step_id not in done or powered_id not in done:
            notes.append(f"table interference: {step.step_id} or {powered_id} not completed")
            continue
        # good samples only: those the gyro flagged are never analysed
        powered = output_to_dph(done.step(powered_id, ("gyro",))["gyro"], nominal_sf)
        off = output_to_dph(done.step(step.step_id, ("gyro",))["gyro"], nominal_sf)
        try:
            result = compare(np.asarray(powered), np.asarray(off), record.sample_rate_hz)
        except ValueError as exc:
            notes.append(f"table interference {step.step_id}: {exc}")
            continue
        out.append(InterferenceEntry(powered_id, step.step_id, step.setpoint_c, result))
    return tuple(out) or None
