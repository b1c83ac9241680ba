"""The logged data of a mountings plan's completed steps, with the mounting each was made in.

The gyro matrix (section.py) reads dwells and the accelerometer matrix
(accel_section.py) statics, but both pick the completed steps of one kind that
ran in a declared mounting, join their parquet chunks and take the unit's
temperature the same way; one owner keeps the two sections' selections alike.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from gyrocal.models.imu_model import Mounting
from gyrocal.record.logged_steps import completed_attempts
from gyrocal.record.plan_record import PlanRecord, RecordedStep
from gyrocal.record.step_kind import StepKind


@dataclass(frozen=True)
class MountedStep:
    """One completed step's logged table and the mounting it ran in."""

    step_id: str
    step: RecordedStep
    mounting: Mounting
    table: pa.Table


def mounted_steps(run_dir: Path, plan: PlanRecord, events: list[dict[str, Any]],
                  kind: StepKind, columns: Sequence[str], notes: list[str],
                  missing_note: str) -> Iterator[MountedStep]:
    """Completed ``kind`` steps run in a declared mounting whose logs hold ``columns``; a step
    without them is left out with ``missing_note`` (formatted with ``step_id``) in ``notes``."""
    mountings = {m.name: Mounting(m.up_axis, m.sign) for m in plan.mountings}
    for step_id, event in completed_attempts(events).items():
        step = plan.step(step_id)
        if step is None or step.kind != kind or step.mounting not in mountings:
            continue
        tables = [pq.read_table(Path(run_dir) / rel) for rel in event["chunks"]]
        table = pa.concat_tables(tables) if len(tables) > 1 else tables[0]
        if not all(c in table.column_names for c in columns):
            notes.append(missing_note.format(step_id=step_id))
            continue
        yield MountedStep(step_id, step, mountings[step.mounting], table)


def unit_temp_c(table: pa.Table, good: np.ndarray) -> float:
    """The unit's mean temperature over the good samples: its own sensor where it reports
    one, else the chamber's."""
    sensor = table.column("sensor_temp_c").to_numpy()[good]
    chamber = table.column("chamber_temp_c").to_numpy()[good]
    temp = sensor[np.isfinite(sensor)] if np.isfinite(sensor).any() else chamber
    return float(np.mean(temp))
