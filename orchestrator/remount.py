"""The remount step of a multi-axis IMU calibration: an operator turns the fixture.

A remount is the one step a person does in the middle of the night's plan,
so it is built like a hand-over with a check at the end:

1. the table is stopped and its rate read back as zero before anyone is
   asked to touch it; the chamber holds its setpoint;
2. the instruction ("mount Y (face B: IMU +Y up along the table axis)") is
   printed and journaled as ``operator_needed`` (which notifies the
   station's ``needs_operator`` targets);
3. the run waits for the operator's confirmation: ``gyrocal confirm RUN_DIR``
   writes ``RUN_DIR/CONFIRM`` naming the mounting. In a dry run the simulated
   fixture turns by itself;
4. the mount check turns the table at :data:`CHECK_RATE_DPS` for a moment and
   requires the declared IMU axis, with its declared sign, to carry the table
   rate. A wrong remount is a clear fault before any data are taken, never a
   wrong calibration.

Why a turn and not the static Earth-rate pattern: at mid latitudes the
vertical and horizontal Earth-rate components are of one size (11.6 and
9.6 deg/h at 50.46°) and comparable to an IMU's bias before calibration, and
the STIM300 gyro datagram carries no accelerometers for a gravity check; a
10 deg/s turn is 3,600 times the Earth rate and leaves no doubt.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from gyrocal.instruments.factory import Instruments
from gyrocal.models.imu_model import AXES, Mounting
from gyrocal.orchestrator.acquisition import Acquisition
from gyrocal.orchestrator.conditions import Conditions
from gyrocal.orchestrator.machine import RunStateMachine
from gyrocal.orchestrator.plan import PlanStep
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.run_errors import RunFaultError
from gyrocal.record.journal import Journal, JournalEvent
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.step_kind import StepKind

CONFIRM_FILE = "CONFIRM"
CHECK_RATE_DPS = 10.0        # the mount check's table rate
CHECK_SETTLE_S = 1.0         # after reaching it, before reading
CHECK_READ_S = 0.5           # gyro data averaged for the check
MIN_ALIGNMENT = 0.95         # cosine between the sensed rate vector and the declared up axis


class MountCheckError(Exception):
    """The IMU is not mounted the way the step declares."""


class FixtureOperator(Protocol):
    """Whoever turns the fixture: a person at the table, or the simulated fixture."""

    def request(self, name: str, mounting: Mounting, instruction: str) -> None:
        """Ask for the mounting (returns at once)."""

    def confirmed(self, name: str) -> bool:
        """Has the mounting been done and confirmed?"""

    def resumed(self, name: str, mounting: Mounting) -> None:
        """A resumed run continues in ``mounting`` (checked by the engine right after)."""


@dataclass
class FileConfirmOperator:
    """A person: told on the console, confirms with ``gyrocal confirm RUN_DIR``."""

    run_dir: Path

    @property
    def confirm_file(self) -> Path:
        return self.run_dir / CONFIRM_FILE

    def request(self, name: str, mounting: Mounting, instruction: str) -> None:
        print(f"gyrocal: OPERATOR: {instruction}; then `gyrocal confirm {self.run_dir}`",
              flush=True)

    def confirmed(self, name: str) -> bool:
        try:
            text = self.confirm_file.read_text(encoding="utf-8").strip()
        except FileNotFoundError:
            return False
        if text not in ("", name):
            return False     # a confirmation for another mounting: not this one
        self.confirm_file.unlink(missing_ok=True)
        return True

    def resumed(self, name: str, mounting: Mounting) -> None:
        """The fixture is where the operator left it; the mount check will tell."""


class SimulatedFixtureLike(Protocol):
    def mount(self, requested: Mounting) -> Mounting: ...


@dataclass
class SimulatedFixtureOperator:
    """A dry run: the simulated fixture turns by itself when asked."""

    fixture: SimulatedFixtureLike

    def request(self, name: str, mounting: Mounting, instruction: str) -> None:
        self.fixture.mount(mounting)

    def confirmed(self, name: str) -> bool:
        return True

    def resumed(self, name: str, mounting: Mounting) -> None:
        # a restarted dry run has a new simulated fixture: it turns to where the run was
        self.fixture.mount(mounting)


def write_confirmation(run_dir: Path, mounting: str | None) -> Path:
    """What ``gyrocal confirm`` does: the engine picks it up between its polls."""
    path = Path(run_dir) / CONFIRM_FILE
    path.write_text(f"{mounting or ''}\n", encoding="utf-8")
    return path


def wait_confirmed(operator: FixtureOperator, name: str, poll_s: float,
                   on_wait=None) -> None:
    """Block (wall time: a person's pace) until ``operator`` confirms ``name``."""
    while not operator.confirmed(name):
        if on_wait is not None:
            on_wait()
        time.sleep(poll_s)


def check_mounting(rate_xyz: np.ndarray, mounting: Mounting, table_rate_dps: float) -> dict:
    """Judge a block of three-axis samples taken while the table turns at ``table_rate_dps``.

    Returns what was sensed (for the journal); raises :class:`MountCheckError`
    naming the axis that did carry the rate.
    """
    mean = np.nanmean(np.asarray(rate_xyz, dtype=float), axis=0)
    if mean.shape != (3,) or not np.all(np.isfinite(mean)):
        raise MountCheckError("mount check: the gyro gave no usable three-axis data")
    sensed = mean / table_rate_dps                 # ≈ the up axis in IMU coordinates
    norm = float(np.linalg.norm(sensed))
    found_axis = int(np.argmax(np.abs(sensed)))
    found = Mounting(found_axis, 1.0 if sensed[found_axis] > 0 else -1.0)
    cosine = float(np.dot(sensed, mounting.up_vector()) / norm) if norm > 0 else 0.0
    fields = {"sensed_per_table_rate": [round(float(v), 6) for v in sensed],
              "declared_up": mounting.label, "sensed_up": found.label,
              "alignment": round(cosine, 6)}
    if cosine < MIN_ALIGNMENT:
        shown = ", ".join(f"{a}={v:+.3f}" for a, v in zip(AXES, sensed, strict=True))
        raise MountCheckError(
            f"mount check failed: declared IMU {mounting.label} up, but a "
            f"{table_rate_dps:g} deg/s turn of the table is sensed on {found.label} "
            f"(per unit table rate: {shown}); remount the fixture as declared and "
            "confirm again (`gyrocal resume` repeats the remount)")
    return fields


class RemountExecutor:
    """The executor of ``remount`` steps (and the mount re-check of a resumed run)."""

    def __init__(self, instruments: Instruments, conditions: Conditions, acquisition: Acquisition,
                 machine: RunStateMachine, journal: Journal, folder: RunFolder, progress: Progress,
                 operator: FixtureOperator, mountings: Mapping[str, Mounting], poll_s: float,
                 attempts_before: Callable[[str], int], elapsed_s: Callable[[], float],
                 completed_fields: Callable[[PlanStep], dict[str, Any]] = lambda step: {}
                 ) -> None:
        self.inst = instruments
        self.conditions = conditions
        self.acquisition = acquisition
        self.machine = machine
        self.journal = journal
        self.folder = folder
        self.progress = progress
        self.operator = operator
        self.mountings = dict(mountings)
        self.poll_s = poll_s
        self.attempts_before = attempts_before
        self.elapsed_s = elapsed_s
        #: what the step_completed line adds (a dry run's simulated state: engine.Rehearsal)
        self.completed_fields = completed_fields

    def mounting_of(self, step: PlanStep) -> Mounting:
        if step.mounting not in self.mountings:
            raise RunFaultError(f"plan step {step.step_id}: mounting {step.mounting!r} but the "
                                "run has no fixture operator for it")
        return self.mountings[step.mounting]

    def execute(self, step: PlanStep) -> None:
        """Hand the table to the operator, wait for the confirmation, check the mounting."""
        mounting = self.mounting_of(step)
        attempt = self.attempts_before(step.step_id) + 1
        self.journal.append(JournalEvent.STEP_STARTED, step_id=step.step_id, kind=StepKind.REMOUNT,
                            mounting=step.mounting, attempt=attempt)
        self.conditions.set_table_rate(0.0)
        reading = self.inst.table.read_rate_dps()
        if abs(reading) > self.conditions.rate_band(0.0):
            raise RunFaultError(f"table: reads {reading:g} deg/s after stop; not handing it to "
                                "the operator for a remount")
        self.inst.table.stop()
        self.machine.pause()
        self.journal.append(JournalEvent.OPERATOR_NEEDED, step_id=step.step_id, mounting=step.mounting,
                            instruction=step.label, table_rate_dps=reading)
        self.folder.update_manifest(state="needs_operator")
        self.progress.update(paused=True)
        self.operator.request(step.mounting, mounting, step.label or step.mounting)
        wait_confirmed(self.operator, step.mounting, self.poll_s,
                       on_wait=self.conditions.poll_chamber)
        self.journal.append(JournalEvent.OPERATOR_CONFIRMED, step_id=step.step_id, mounting=step.mounting)
        self.progress.update(paused=False, step_started_s=self.elapsed_s())
        self.folder.update_manifest(state="running")
        self.machine.unpause()
        self.inst.table.set_rate_mode()
        fields = self.mount_check(step, mounting)
        self.journal.append(JournalEvent.STEP_COMPLETED, step_id=step.step_id, attempt=attempt,
                            **fields, **self.completed_fields(step))

    def ensure(self, step: PlanStep) -> None:
        mounting = self.mounting_of(step)
        self.operator.resumed(step.mounting, mounting)
        self.journal.append(JournalEvent.MOUNT_RECHECK, step_id=step.step_id, mounting=step.mounting,
                            **self.mount_check(step, mounting))

    def mount_check(self, step: PlanStep, mounting: Mounting) -> dict[str, Any]:
        """Turn the table briefly; the declared IMU axis must sense it (``remount.py``)."""
        self.conditions.set_table_rate(CHECK_RATE_DPS, None, CHECK_SETTLE_S)
        gyro = self.inst.gyro
        gyro.flush()
        n = max(8, int(self.inst.sample_rate_hz * CHECK_READ_S))
        self.acquisition.clock.elapse_reading(n / self.inst.sample_rate_hz)
        block = gyro.read_samples(n, timeout_s=self.acquisition.read_timeout_s(CHECK_READ_S))
        self.conditions.set_table_rate(0.0)
        rate_xyz = block.rate_xyz
        if rate_xyz is None:
            raise RunFaultError(f"step {step.step_id}: the gyro driver gives one axis; a "
                                "multi-axis calibration needs all three (STIM300 datagram)")
        try:
            return check_mounting(rate_xyz, mounting, CHECK_RATE_DPS)
        except MountCheckError as exc:
            raise RunFaultError(f"step {step.step_id}: {exc}") from None
