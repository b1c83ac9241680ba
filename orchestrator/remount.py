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
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from gyrocal.models.imu_model import AXES, Mounting

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
