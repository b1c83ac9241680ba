"""The procedure as typed data: what to measure, at which temperatures and rates, what passes.

Frozen dataclasses only, and the language's constants (choices, defaults, plausibility
bounds) beside them, so the plan, the engine and the language reference read one
vocabulary. ``parser.py`` builds these from a file; nothing here reads a file.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from gyrocal.models.imu_model import Mounting
from gyrocal.orchestrator.station import Station


class TestKind(str, Enum):
    """What a test of the procedure measures (its ``kind:``); ``plan.py`` expands each into
    steps of one or more :class:`~gyrocal.record.step_kind.StepKind`."""

    __test__ = False   # not a pytest test class, whatever its name

    STATIC = "static"
    SF_SWEEP = "sf_sweep"
    ALLAN = "allan"
    TABLE_INTERFERENCE = "table_interference"
    THRESHOLD = "threshold"
    RATE_LIMIT = "rate_limit"
    FREQUENCY_RESPONSE = "frequency_response"
    MAGNETIC = "magnetic"
    TILT_LINEARITY = "tilt_linearity"
    TURN_ON = "turn_on"
    TURN_ON_REPEATABILITY = "turn_on_repeatability"

    def __str__(self) -> str:     # as written in the procedure file
        return self.value


PROCEDURE_VERSION = 1
OUTPUT_UNITS = ("deg/s", "deg/h", "rad/s", "V", "LSB")
DIRECTIONS = ("both", "positive", "negative")
SPACINGS = ("linear", "log")
#: the ``kind:`` values, in the order the language reference lists them
TEST_KINDS = tuple(kind.value for kind in TestKind)

#: Frequency-response defaults: whole sinusoid periods logged per frequency (at least
#: ``min_duration``), and periods turned before logging so the unit's transient has gone.
DEFAULT_FR_CYCLES = 10
DEFAULT_FR_SETTLE_CYCLES = 3
#: A sinusoid needs this many samples per period for its amplitude and phase (and the
#: simulator's first-order hold of the table rate) to be meaningful.
MIN_SAMPLES_PER_PERIOD = 10
#: the vendor notes' angle points of the tilt test (indexing head), by name
TILT_POINTS = {"vendor_90": tuple(float(a) for a in range(-90, 91, 15)),
               "vendor_30": tuple(float(a) for a in range(-30, 31, 5))}
#: Input-rate limit defaults: a rate leaves the linear fit when its output is more than this
#: many % of the fitted output away from it; the fit uses this many of the lowest rates.
DEFAULT_LINEARITY_TOLERANCE_PCT = 1.0
DEFAULT_FIT_RATES = 3
#: Threshold defaults (IEEE Std 952 §3 "threshold": the smallest input change whose output
#: change is at least half the expected one; the confidence is the one-sided level at which
#: the mean output change counts as resolved against the noise of the two means).
DEFAULT_THRESHOLD_CONFIDENCE = 0.95
DEFAULT_THRESHOLD_ERROR_FRACTION = 0.5
MAX_LIST = 1000           # rates per sweep, steps per sequence: beyond this it is a typo
MAX_DURATION_S = 7 * 86400.0
#: Floors below which a ramp or an acceleration is a typo, not a choice: 0.01 °C/min is 0.6 °C
#: an hour (a 100 °C step would take a week) and 0.01 deg/s² takes 50 s to reach 0.5 deg/s.
#: The adversarial pass validated a 1e-9 acceleration (an ETA of 327 million hours).
MIN_RAMP_C_PER_MIN = 0.01
MIN_ACCEL_DPS2 = 0.01
#: The longest a procedure may take (its ETA) unless it declares ``max_duration:``: nobody
#: plans two unattended weeks on a rate table by accident.
DEFAULT_MAX_ETA_S = 14 * 86400.0
MAX_DECLARED_DURATION_S = 90 * 86400.0


# -- the typed result -------------------------------------------------------------------

@dataclass(frozen=True)
class UnitUnderTest:
    model: str
    serial: str
    output_units: str
    nominal_scale_factor: float   # output units per deg/s


@dataclass(frozen=True)
class ChamberSafety:
    min_temp_c: float
    max_temp_c: float
    max_ramp_c_per_min: float


@dataclass(frozen=True)
class TableSafety:
    max_rate_dps: float
    max_accel_dps2: float


@dataclass(frozen=True)
class Safety:
    chamber: ChamberSafety
    table: TableSafety


@dataclass(frozen=True)
class SoakCriterion:
    """Stable = within ±tolerance_c of the setpoint for hold_s; give up after max_wait_s."""

    tolerance_c: float
    hold_s: float
    max_wait_s: float


@dataclass(frozen=True)
class DataQuality:
    max_lost_frame_fraction: float   # lost + CRC-failed frames per logged step
    max_step_repeats: int            # a bad step is repeated at most this many times
    # how far a measured scale factor may lie from the nominal one before the run is
    # INVALID rather than judged (metrology/sanity.py)
    sf_tolerance_pct: float = 5.0


@dataclass(frozen=True)
class Defaults:
    """What tests and steps inherit; None where the procedure gave no default."""

    ramp_c_per_min: float | None
    soak: SoakCriterion | None
    dwell_s: float | None
    settle_s: float | None
    accel_dps2: float | None
    sample_rate_hz: float


@dataclass(frozen=True)
class RateSchedule:
    spacing: str        # linear | log
    start_dps: float
    stop_dps: float
    count: int


@dataclass(frozen=True)
class StaticTest:
    """Table at rest for duration_s: the bias at this temperature."""

    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.STATIC


@dataclass(frozen=True)
class TableInterferenceTest:
    """Two statics at rest: the table's drive powered holding zero rate, then off (interlock
    open); the report compares them (drift ratio, spectral lines: analysis/environment/interference.py)."""

    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.TABLE_INTERFERENCE


@dataclass(frozen=True)
class MagneticTest:
    """Static dwells at +B, 0 and -B along the station's coil axis (Helmholtz coil driven by
    the station's supply): the bias sensitivity in deg/(h·T) (analysis/environment/magnetic.py)."""

    field_t: float            # |B| of the +B and -B dwells, tesla
    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.MAGNETIC


@dataclass(frozen=True)
class TiltLinearityTest:
    """An inclinometer's static test with the table (axis horizontal) as the indexing head:
    a dwell at each angle point, then a zero-stability hold at 0 (analysis/environment/tilt_linearity.py)."""

    angles_deg: tuple[float, ...]
    points: str               # the name of the angle set (TILT_POINTS) or "listed"
    dwell_s: float
    settle_s: float
    zero_stability_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.TILT_LINEARITY


@dataclass(frozen=True)
class AllanTest:
    """A long static hold for the Allan variance (noise terms Q, N, B, K, R)."""

    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.ALLAN


@dataclass(frozen=True)
class SweepTest:
    """Scale factor: dwell at +rate then -rate for each rate (SF = (V+ - V-) / 2Ω)."""

    rates_dps: tuple[float, ...]       # magnitudes, > 0, in order of execution
    schedule: RateSchedule | None      # how rates_dps was generated, if it was
    directions: str                    # both | positive | negative
    dwell_s: float
    settle_s: float
    accel_dps2: float
    min_revolutions: int | None        # dwell rounded up to whole table revolutions, at least this many
    repeats: int
    label: str | None
    kind: TestKind = TestKind.SF_SWEEP


@dataclass(frozen=True)
class ThresholdTest:
    """Threshold and resolution (IEEE Std 952 / 1431): small rate increments about each base.

    At each base rate the table alternates base, base+increment, base, … so every
    increment's output change is taken against the mean of the base dwells on either
    side (a linear bias drift cancels). The smallest increment whose change is resolved
    at ``confidence`` and lies within ``max_error_fraction`` of the commanded change is
    the threshold (at a zero base) or the resolution (at a non-zero base).
    """

    base_rates_dps: tuple[float, ...]   # signed; 0 for the threshold
    increments_dps: tuple[float, ...]   # > 0, increasing
    dwell_s: float
    settle_s: float
    accel_dps2: float
    confidence: float
    max_error_fraction: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.THRESHOLD


@dataclass(frozen=True)
class RateLimitTest:
    """Input-rate limits (IEEE Std 952 / 1431): rates walked up to the declared maximum each way.

    The lowest ``fit_rates`` rates (each way) define the linear fit; the maximum input rate
    each way is the largest rate that, with every smaller one, stays within
    ``linearity_tolerance_pct`` of that fit. The plan walks every listed rate (the table's
    limits bound them), so a unit that saturates early costs dwells, never safety.
    """

    rates_dps: tuple[float, ...]       # magnitudes, increasing
    directions: str                    # both | positive | negative
    dwell_s: float
    settle_s: float
    accel_dps2: float
    linearity_tolerance_pct: float
    fit_rates: int
    repeats: int
    label: str | None
    kind: TestKind = TestKind.RATE_LIMIT


@dataclass(frozen=True)
class FrequencyResponseTest:
    """Frequency response (IEEE Std 952 / 1431): the table in synthesis mode (TM-8004
    §4.7.6), a sinusoid of rate amplitude ``amplitude_dps`` at each frequency in turn.

    Each frequency turns ``settle_cycles`` periods, then logs ``cycles`` periods (at least
    ``min_duration_s``); the report fits sines to the gyro output and the table rate
    (analysis/rate/frequency_response.py) for gain and phase, the −3 dB bandwidth and the phase
    at ``phase_at_hz``.
    """

    frequencies_hz: tuple[float, ...]   # increasing
    amplitude_dps: float                # peak rate of the sinusoid
    cycles: int
    settle_cycles: int
    min_duration_s: float
    phase_at_hz: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.FREQUENCY_RESPONSE

    def duration_s(self, freq_hz: float) -> float:
        return max(self.min_duration_s, self.cycles / freq_hz)

    def settle_s(self, freq_hz: float) -> float:
        return self.settle_cycles / freq_hz


@dataclass(frozen=True)
class TurnOnTest:
    """Turn-on time and warm-up (IEEE Std 952 / IEEE Std 1431): the station's supply switches
    the unit off for ``off_s``, then on (the table at rest); the gyro is logged from its first
    frame for ``duration_s``. The report gives the time from the output-on command to the
    first valid frame, the warm-up fit (analysis/thermal/warmup.py) and the time until the bias stays
    within ±``band_dph`` of its settled value."""

    off_s: float
    duration_s: float
    band_dph: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.TURN_ON


@dataclass(frozen=True)
class TurnOnRepeatabilityTest:
    """Turn-on-to-turn-on bias repeatability (IEEE Std 952 / IEEE Std 1431): ``cycles`` power
    cycles, each off for ``off_s`` (the cool-down), on, ``settle_s`` after the first frame,
    then ``duration_s`` logged; the repeatability is the standard deviation of the cycles'
    biases, u from N (analysis/thermal/warmup.py), the in-run bias stability beside it."""

    cycles: int
    off_s: float
    settle_s: float
    duration_s: float
    repeats: int
    label: str | None
    kind: TestKind = TestKind.TURN_ON_REPEATABILITY


Test = (StaticTest | AllanTest | SweepTest | TableInterferenceTest | ThresholdTest
        | RateLimitTest | FrequencyResponseTest | MagneticTest | TiltLinearityTest | TurnOnTest
        | TurnOnRepeatabilityTest)


@dataclass(frozen=True)
class TemperatureStep:
    setpoint_c: float
    ramp_c_per_min: float
    soak: SoakCriterion
    tests: tuple[Test, ...]
    label: str | None


#: ``mounting_order``: every temperature in one mounting, then remount (what operators
#: usually do: three remounts a night), or every mounting at each temperature (the
#: vendor notes' method: the fixture is turned three times at each temperature).
MOUNTING_ORDERS = ("temperatures_inside", "mountings_inside")


@dataclass(frozen=True)
class MountingSpec:
    """One face of the hexahedron fixture: which IMU axis points up the table axis."""

    name: str                 # in step ids (``MX.T01.sf.+10dps``): letters, digits, - and _
    up: Mounting
    face: str | None = None   # the fixture face the operator is told to use

    @property
    def instruction(self) -> str:
        face = f"face {self.face}: " if self.face else ""
        return f"mount {self.name} ({face}IMU {self.up.label} up along the table axis)"


@dataclass(frozen=True)
class AcceptanceLimit:
    name: str
    metric: str        # key path in results.json
    max: float | None
    min: float | None
    unit: str | None
    #: how the value's expanded uncertainty enters the decision (metrology/decision.py)
    decision_rule: str = "simple"

    def passes(self, value: float) -> bool:
        if self.max is not None and not value <= self.max:
            return False
        return not (self.min is not None and not value >= self.min)


@dataclass(frozen=True)
class Procedure:
    version: int
    name: str
    description: str | None
    unit_under_test: UnitUnderTest
    station: Station
    safety: Safety
    defaults: Defaults
    data_quality: DataQuality
    sequence: tuple[TemperatureStep, ...]
    acceptance: tuple[AcceptanceLimit, ...]
    file: str                  # as given, for messages
    path: Path                 # resolved
    files: tuple[Path, ...]    # the procedure, its includes and the station file (for the manifest)
    mountings: tuple[MountingSpec, ...] = ()   # a multi-axis IMU calibration; () for one axis
    mounting_order: str = "temperatures_inside"
    #: the longest the plan's ETA may be: ``max_duration:`` when declared, else 14 days
    max_duration_s: float = DEFAULT_MAX_ETA_S
    max_duration_declared: bool = False
