"""What a plan step does: the kinds plan.json and the journal name, one enum."""

from __future__ import annotations

from enum import Enum


class StepKind(str, Enum):
    """What a plan step does; the engine has one executor per kind."""

    RAMP = "ramp"          # chamber to a new setpoint at the procedure's rate
    SOAK = "soak"          # wait for the temperature to hold within tolerance
    STATIC = "static"      # log at rest
    ALLAN = "allan"        # log a long hold at rest (noise terms)
    DWELL = "dwell"        # log at a constant table rate
    DRIVE_OFF = "drive_off"  # log at rest with the table's drive off (interlock open)
    REMOUNT = "remount"    # an operator turns the IMU fixture (multi-axis procedures)
    THRESHOLD = "threshold"  # log at a base rate or a small increment above it (threshold test)
    RATE_LIMIT = "rate_limit"  # log at a rate of the walk up to the declared maximum
    FREQUENCY_RESPONSE = "frequency_response"  # log while the table turns a sinusoid
    MAGNETIC = "magnetic"  # log at rest with the station's coil at a set field
    TILT = "tilt"          # log with the table (axis horizontal) held at an angle point
    TURN_ON = "turn_on"    # the supply switches the unit off, then on; logged from its first frame
    TURN_ON_CYCLE = "turn_on_cycle"  # one power cycle of a repeatability test, logged after settling

    def __str__(self) -> str:     # as written in plan.json and the journal
        return self.value

    @property
    def logs_data(self) -> bool:
        return self in (StepKind.STATIC, StepKind.ALLAN, StepKind.DWELL, StepKind.DRIVE_OFF,
                        StepKind.THRESHOLD, StepKind.RATE_LIMIT, StepKind.FREQUENCY_RESPONSE,
                        StepKind.MAGNETIC, StepKind.TILT, StepKind.TURN_ON,
                        StepKind.TURN_ON_CYCLE)
