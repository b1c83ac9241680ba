"""The logged data of a mountings plan's completed steps, with the mounting each was made in.

The gyro matrix (section.py) reads dwells and the accelerometer matrix
(accel_section.py) statics, but both pick the completed steps of one kind that
ran in a declared mounting, read their samples through the run record and take the unit's
temperature the same way; one owner keeps the two sections' selections alike.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.models.imu_model import Mounting
from gyrocal.record.plan_record import PlanRecord, RecordedStep
from gyrocal.record.samples import RunSamples, StepSamples
from gyrocal.record.step_kind import StepKind


@dataclass(frozen=True)
class MountedStep:
    """One completed step's logged samples (all rows: each section applies its own flags) and
    the mounting it ran in."""

    step_id: str
    step: RecordedStep
    mounting: Mounting
    samples: StepSamples

    def good(self, flags: Sequence[str]) -> np.ndarray:
        """Rows no flag column in ``flags`` marks (a flag column the chunks lack marks none)."""
        good = np.ones(self.samples.n, dtype=bool)
        for name in flags:
            if name in self.samples:
                good &= self.samples[name] == 0
        return good


#: what :func:`unit_temp_c` reads, besides each section's own columns and flags
TEMPERATURE_COLUMNS = ("sensor_temp_c", "chamber_temp_c")


def mounted_steps(run_dir: Path, plan: PlanRecord, events: list[dict[str, Any]],
                  kind: StepKind, columns: Sequence[str], notes: list[str],
                  missing_note: str, flags: Sequence[str]) -> Iterator[MountedStep]:
    """Completed ``kind`` steps run in a declared mounting whose logs hold ``columns``; a step
    without them is left out with ``missing_note`` (formatted with ``step_id``) in ``notes``.

    Only ``columns``, the ``flags`` the section will judge rows by (:meth:`MountedStep.good`)
    and the temperatures are read: an IMU chunk holds some twenty columns (accelerometers,
    inclinometers, three temperatures, statuses), and reading every one of them for each of a
    six-mounting plan's 330 steps was most of its report's time."""
    mountings = {m.name: Mounting(m.up_axis, m.sign) for m in plan.mountings}
    run = RunSamples(run_dir, events)
    wanted = [*columns, *flags, *TEMPERATURE_COLUMNS]
    for step_id in run.logged:
        step = plan.step(step_id)
        if step is None or step.kind != kind or step.mounting not in mountings:
            continue
        logged = run.step(step_id, wanted, good_only=False)
        if not all(c in logged for c in columns):
            notes.append(missing_note.format(step_id=step_id))
            continue
        yield MountedStep(step_id, step, mountings[step.mounting], logged)


def unit_temp_c(samples: StepSamples, good: np.ndarray) -> float:
    """The unit's mean temperature over the good samples: its own sensor where it reports
    one, else the chamber's."""
    sensor = samples["sensor_temp_c"][good]
    chamber = samples["chamber_temp_c"][good]
    temp = sensor[np.isfinite(sensor)] if np.isfinite(sensor).any() else chamber
    return float(np.mean(temp))
