"""The procedure file: what to measure, at which temperatures and rates, and what passes.

Everything is checked here, before anything moves: the schema, the units,
and every setpoint, rate, ramp rate and acceleration against both the
procedure's own safety limits and the station's hard limits. A wrong value at
hour 14 of an overnight run costs a night; here it costs one edit. Every
problem is collected and raised together as one :class:`ProcedureError`.

Values left out of a test or a temperature step come from ``defaults``; a
value that is in neither place is an error naming both, so no duration is
ever silently made up.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrocal.inputs import YamlDocument, load_yaml, outside_reference
from gyrocal.instruments.gyro.datagram_types import layout_of
from gyrocal.instruments.table.acutrol_protocol import RATE_DECIMALS, commanded_rate_dps
from gyrocal.metrology.metrics import METRICS, NEEDS_TEXT, units_match
from gyrocal.models.imu_model import Mounting
from gyrocal.orchestrator.station import Station, load_station, parse_station
from gyrocal.problems import KeyPath, ProcedureError, sort_problems
from gyrocal.schema import (
    Context,
    Fields,
    choice,
    duration,
    file_name,
    integer,
    number,
    quantity,
    serial_number,
    text,
)
from gyrocal.units import (
    ACCELERATION,
    FREQUENCY,
    RATE,
    TEMPERATURE,
    TEMPERATURE_RATE,
    UnitError,
    describe,
    format_number,
)

PROCEDURE_VERSION = 1
OUTPUT_UNITS = ("deg/s", "deg/h", "rad/s", "V", "LSB")
DIRECTIONS = ("both", "positive", "negative")
SPACINGS = ("linear", "log")
TEST_KINDS = ("static", "sf_sweep", "allan", "table_interference", "threshold", "rate_limit",
              "frequency_response", "magnetic", "tilt_linearity", "turn_on",
              "turn_on_repeatability")
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
    kind: str = "static"


@dataclass(frozen=True)
class TableInterferenceTest:
    """Two statics at rest: the table's drive powered holding zero rate, then off (interlock
    open); the report compares them (drift ratio, spectral lines: analysis/environment/interference.py)."""

    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: str = "table_interference"


@dataclass(frozen=True)
class MagneticTest:
    """Static dwells at +B, 0 and -B along the station's coil axis (Helmholtz coil driven by
    the station's supply): the bias sensitivity in deg/(h·T) (analysis/environment/magnetic.py)."""

    field_t: float            # |B| of the +B and -B dwells, tesla
    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: str = "magnetic"


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
    kind: str = "tilt_linearity"


@dataclass(frozen=True)
class AllanTest:
    """A long static hold for the Allan variance (noise terms Q, N, B, K, R)."""

    duration_s: float
    settle_s: float
    repeats: int
    label: str | None
    kind: str = "allan"


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
    kind: str = "sf_sweep"


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
    kind: str = "threshold"


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
    kind: str = "rate_limit"


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
    kind: str = "frequency_response"

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
    kind: str = "turn_on"


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
    kind: str = "turn_on_repeatability"


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


def _mounting_axis(value: object) -> Mounting:
    if not isinstance(value, str):
        raise UnitError(f"must be an IMU axis with its sign (+x, -y, z), got {describe(value)}")
    try:
        return Mounting.parse(value)
    except ValueError as exc:
        raise UnitError(str(exc)) from None


def _mounting_name(value: object) -> str:
    name = text(value)
    if not name or not all(c.isalnum() or c in "-_" for c in name):
        raise UnitError(f"must be letters, digits, - or _ (it is part of every step id), got {name!r}")
    return name


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


# -- loading ----------------------------------------------------------------------------

def load_procedure(
    path: str | os.PathLike[str], station_path: str | os.PathLike[str] | None = None, *,
    allow_outside: bool = False,
) -> Procedure:
    """Read and validate a procedure; ``station_path`` overrides its ``station:`` key.

    Raises :class:`ProcedureError` with every problem found in the procedure,
    its includes and its station. Files the procedure names (its station, the station's
    gyro model) must lie near it unless ``allow_outside`` (see ``outside_reference``);
    ``station_path`` is the user's own choice on the command line and is not confined.
    """
    document = load_yaml(path)
    ctx = Context(document, allow_outside=allow_outside)
    procedure = _Parser(ctx, station_path).procedure(document.data)
    if ctx.problems:
        raise ProcedureError(sort_problems(ctx.problems))
    assert procedure is not None
    return procedure


def _duration(positive: bool = True) -> Callable[[object], float]:
    base = duration(positive=positive)

    def convert(value: object) -> float:
        seconds = base(value)
        if seconds > MAX_DURATION_S:
            raise UnitError(f"{value!r} is longer than 7 days; a typo?")
        return seconds
    return convert


def _list(ctx: Context, path: KeyPath, value: object, what: str, *, allow_empty: bool = False) -> list:
    if not isinstance(value, list):
        ctx.report(path, f"{what} must be a list, got {describe(value)}")
        return []
    if not value and not allow_empty:
        ctx.report(path, f"{what} must not be empty")
    if len(value) > MAX_LIST:
        ctx.report(path, f"{what} has {len(value)} entries; at most {MAX_LIST} are allowed")
        return []
    return value


@dataclass(frozen=True)
class _Limit:
    value: float
    what: str         # "table limit"
    where: str        # "procedure safety.table.max_rate_dps"


class _Parser:
    def __init__(self, ctx: Context, station_path: str | os.PathLike[str] | None) -> None:
        self.ctx = ctx
        self.document: YamlDocument = ctx.document
        self.station_path = station_path
        self.station: Station | None = None
        self.station_files: list[Path] = []
        self.safety: Safety | None = None
        self.output_units: str | None = None   # the unit under test's, once read
        # defaults that were given but invalid: already reported, so a test that
        # inherits them is not also told the key is missing
        self.broken_defaults: set[str] = set()

    # -- top level ------------------------------------------------------------------------
    def procedure(self, data: object) -> Procedure | None:
        ctx = self.ctx
        fields = Fields(ctx, (), data, "a procedure")
        if not fields.valid:
            return None
        version = fields.take("version", integer())
        if version is not None and version != PROCEDURE_VERSION:
            ctx.report(("version",), f"unsupported procedure version {version}; "
                       f"this gyrocal reads version {PROCEDURE_VERSION}")
        name = fields.take("name", text)
        description = fields.take("description", text, required=False)
        uut = self.unit_under_test(fields)
        self.output_units = uut.output_units
        self.station = self.load_station(fields)
        self.safety = self.safety_limits(fields)
        defaults = self.defaults(fields)
        quality = self.data_quality(fields)
        present, raw = fields.raw("sequence")
        if not present:
            ctx.report(("sequence",), "required key is missing")
        sequence = tuple(
            self.temperature_step(("sequence", index), item, defaults)
            for index, item in enumerate(_list(ctx, ("sequence",), raw, "sequence"))
        ) if present else ()
        acceptance = self.acceptance(fields, sequence)
        mountings = self.mountings(fields)
        order = fields.take("mounting_order", choice(MOUNTING_ORDERS), required=False,
                            default="temperatures_inside")
        if fields.has("mounting_order") and not mountings:
            ctx.report(fields.child("mounting_order"), "only meaningful with a mountings: list")
        max_duration = fields.take("max_duration", duration(), required=False)
        if max_duration is not None and max_duration > MAX_DECLARED_DURATION_S:
            ctx.report(fields.child("max_duration"), "longer than 90 days; a typo?")
        fields.raw("templates")   # free-form: a home for YAML anchors (&sweep) used elsewhere
        fields.finish()
        files = tuple(self.document.files) + tuple(self.station_files)
        return Procedure(version, name, description, uut, self.station, self.safety, defaults,
                         quality, sequence, acceptance, self.document.file, self.document.path,
                         files, mountings, order,
                         max_duration if max_duration is not None else DEFAULT_MAX_ETA_S,
                         max_duration is not None)

    def mountings(self, parent: Fields) -> tuple[MountingSpec, ...]:
        present, raw = parent.raw("mountings")
        if not present:
            return ()
        specs: list[MountingSpec] = []
        names: dict[str, int] = {}
        ups: dict[Mounting, int] = {}
        for index, item in enumerate(_list(self.ctx, ("mountings",), raw, "mountings")):
            path: KeyPath = ("mountings", index)
            fields = Fields(self.ctx, path, item, "a mounting")
            if not fields.valid:
                continue
            name = fields.take("name", _mounting_name)
            up = fields.take("up", _mounting_axis)
            face = fields.take("face", text, required=False)
            fields.finish()
            if name is not None and name in names:
                self.ctx.report(fields.child("name"),
                                f"name {name!r} is used twice (also mountings[{names[name]}])")
            if up is not None and up in ups:
                self.ctx.report(fields.child("up"), f"IMU {up.label} up is already "
                                f"mountings[{ups[up]}]")
            if name is not None and up is not None:
                names.setdefault(name, index)
                ups.setdefault(up, index)
                specs.append(MountingSpec(name, up, face))
        axes = {spec.up.up_axis for spec in specs}
        if specs and len(specs) == len(raw if isinstance(raw, list) else ()) and len(axes) < 3:
            missing = ", ".join(a for i, a in enumerate("xyz") if i not in axes)
            self.ctx.report(("mountings",), f"the three-axis matrix needs every IMU axis up once; "
                            f"no mounting has {missing} up")
        return tuple(specs)

    def section(self, parent: Fields, key: str, *, required: bool = True) -> Fields:
        present, raw = parent.raw(key)
        if not present:
            if required and parent.valid:
                self.ctx.report(parent.child(key), "required key is missing")
            return Fields(self.ctx, parent.child(key), {}, key)
        return Fields(self.ctx, parent.child(key), raw, key)

    def unit_under_test(self, parent: Fields) -> UnitUnderTest:
        fields = self.section(parent, "unit_under_test")
        uut = UnitUnderTest(
            fields.take("model", text),
            fields.take("serial", serial_number),
            fields.take("output_units", choice(OUTPUT_UNITS)),
            fields.take("nominal_scale_factor", number(above=0.0)),
        )
        fields.finish()
        return uut

    def load_station(self, fields: Fields) -> Station | None:
        present, raw = fields.raw("station")
        if self.station_path is not None:
            try:
                station = load_station(self.station_path, allow_outside=self.ctx.allow_outside)
            except ProcedureError as error:
                self.ctx.problems.extend(error.problems)
                return None
            if station.path is not None:
                self.station_files.append(station.path)
            return station
        if not present:
            self.ctx.report(("station",), "required key is missing (or give --station)")
            return None
        if isinstance(raw, dict):
            before = len(self.ctx.problems)
            station = parse_station(self.ctx, ("station",), raw, base_dir=self.document.path.parent,
                                    file=self.document.file, path=None)
            return station if len(self.ctx.problems) == before else None
        try:
            relative = file_name(raw)
        except UnitError as exc:
            self.ctx.report(("station",), "expected the path of a station file (relative to "
                            f"this procedure) or a station mapping: {exc}")
            return None
        target = self.document.path.parent / relative
        refused = None if self.ctx.allow_outside else outside_reference(self.document.path, target)
        if refused is not None:
            self.ctx.report(("station",), refused)
            return None
        display = os.path.normpath(os.path.join(os.path.dirname(self.document.file), relative))
        same_file = Path(display).resolve() == target.resolve()
        try:
            station = load_station(display if same_file else target,
                                   allow_outside=self.ctx.allow_outside)
        except ProcedureError as error:
            self.ctx.problems.extend(error.problems)
            return None
        if station.path is not None:
            self.station_files.append(station.path)
        return station

    def safety_limits(self, parent: Fields) -> Safety:
        fields = self.section(parent, "safety")
        ch = self.section(fields, "chamber")
        chamber = ChamberSafety(
            ch.take("min_temp_c", quantity(TEMPERATURE, -273.15)),
            ch.take("max_temp_c", quantity(TEMPERATURE, -273.15)),
            ch.take("max_ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0)),
        )
        ch.finish()
        tb = self.section(fields, "table")
        table = TableSafety(
            tb.take("max_rate_dps", quantity(RATE, above=0.0)),
            tb.take("max_accel_dps2", quantity(ACCELERATION, above=0.0)),
        )
        tb.finish()
        fields.finish()
        if None not in (chamber.min_temp_c, chamber.max_temp_c) and \
                chamber.min_temp_c >= chamber.max_temp_c:
            self.ctx.report(ch.child("max_temp_c"),
                            f"{format_number(chamber.max_temp_c)} °C must be above min_temp_c "
                            f"{format_number(chamber.min_temp_c)} °C")
        station = self.station
        if station is not None:
            # The procedure's own limits must sit inside what the station can do.
            def station_limit(value: float, what: str, key: str) -> list[_Limit]:
                return [_Limit(value, f"station {what}", f"{station.file}: {key}")]

            lim, tlim = station.chamber.limits, station.table.limits
            self.check_bounds(ch.child("min_temp_c"), chamber.min_temp_c, "°C", lows=station_limit(
                lim.min_temp_c, "chamber limit", "chamber.limits.min_temp_c"))
            self.check_bounds(ch.child("max_temp_c"), chamber.max_temp_c, "°C", highs=station_limit(
                lim.max_temp_c, "chamber limit", "chamber.limits.max_temp_c"))
            self.check_bounds(ch.child("max_ramp_c_per_min"), chamber.max_ramp_c_per_min, "°C/min",
                              highs=station_limit(lim.max_ramp_c_per_min, "chamber limit",
                                                  "chamber.limits.max_ramp_c_per_min"))
            self.check_bounds(tb.child("max_rate_dps"), table.max_rate_dps, "deg/s",
                              highs=station_limit(tlim.max_rate_dps, "table limit",
                                                  "table.limits.max_rate_dps"))
            self.check_bounds(tb.child("max_accel_dps2"), table.max_accel_dps2, "deg/s²",
                              highs=station_limit(tlim.max_accel_dps2, "table limit",
                                                  "table.limits.max_accel_dps2"))
        return Safety(chamber, table)

    # -- limits -----------------------------------------------------------------------------
    def check_bounds(
        self,
        path: KeyPath,
        value: float | None,
        unit: str,
        *,
        lows: list[_Limit] = (),  # type: ignore[assignment]
        highs: list[_Limit] = (),  # type: ignore[assignment]
    ) -> None:
        """Report ``value`` against the tightest limit it violates (if any)."""
        if value is None:
            return
        below = [lim for lim in lows if lim.value is not None and value < lim.value]
        if below:
            tightest = max(below, key=lambda lim: lim.value)
            self.ctx.report(path, f"{format_number(value)} {unit} is below the {tightest.what} "
                            f"{format_number(tightest.value)} {unit} ({tightest.where})")
        above = [lim for lim in highs if lim.value is not None and value > lim.value]
        if above:
            tightest = min(above, key=lambda lim: lim.value)
            self.ctx.report(path, f"{format_number(value)} {unit} exceeds the {tightest.what} "
                            f"{format_number(tightest.value)} {unit} ({tightest.where})")

    def _limits(self, procedure_key: str, station_key: str) -> list[_Limit]:
        """Both limits that bound a value: the procedure's safety block and the station's."""
        limits: list[_Limit] = []
        if self.safety is not None:
            group, field = procedure_key.split(".")
            section = getattr(self.safety, group)
            limits.append(_Limit(getattr(section, field), f"{group} limit",
                                 f"procedure safety.{procedure_key}"))
        if self.station is not None:
            group, _, field = station_key.split(".")
            section = getattr(self.station, group).limits
            limits.append(_Limit(getattr(section, field), f"{group} limit",
                                 f"station {self.station.file}: {station_key}"))
        return limits

    def check_setpoint(self, path: KeyPath, value: float | None) -> None:
        self.check_bounds(
            path, value, "°C",
            lows=self._limits("chamber.min_temp_c", "chamber.limits.min_temp_c"),
            highs=self._limits("chamber.max_temp_c", "chamber.limits.max_temp_c"),
        )

    def check_ramp(self, path: KeyPath, value: float | None) -> None:
        self.check_bounds(path, value, "°C/min", lows=[_Limit(
            MIN_RAMP_C_PER_MIN, "plausible minimum", "a slower ramp is a typo")], highs=self._limits(
            "chamber.max_ramp_c_per_min", "chamber.limits.max_ramp_c_per_min"))

    def check_rate(self, path: KeyPath, value: float | None) -> None:
        self.check_bounds(path, value, "deg/s", highs=self._limits(
            "table.max_rate_dps", "table.limits.max_rate_dps"))

    def check_accel(self, path: KeyPath, value: float | None) -> None:
        self.check_bounds(path, value, "deg/s²", lows=[_Limit(
            MIN_ACCEL_DPS2, "plausible minimum", "a gentler acceleration is a typo")],
            highs=self._limits(
            "table.max_accel_dps2", "table.limits.max_accel_dps2"))

    # -- defaults and quality ---------------------------------------------------------------
    def soak(self, fields: Fields, inherited: SoakCriterion | None,
             prefix: str | None) -> SoakCriterion | None:
        """A soak criterion; keys left out come from ``inherited`` (the defaults, at ``prefix``)."""
        def key(name: str) -> str | None:
            return f"{prefix}.{name}" if prefix else None

        tolerance = self.inherit(fields, "tolerance_c", quantity(TEMPERATURE, above=0.0),
                                 inherited and inherited.tolerance_c, key("tolerance_c"))
        hold = self.inherit(fields, "hold", _duration(), inherited and inherited.hold_s, key("hold"))
        max_wait = self.inherit(fields, "max_wait", _duration(),
                                inherited and inherited.max_wait_s, key("max_wait"))
        fields.finish()
        if None in (tolerance, hold, max_wait):
            return None
        if max_wait < hold:
            self.ctx.report(fields.child("max_wait"),
                            f"max_wait ({format_number(max_wait)} s) is shorter than the hold time "
                            f"({format_number(hold)} s): the soak could never succeed")
        return SoakCriterion(tolerance, hold, max_wait)

    def inherit(self, fields: Fields, key: str, convert: Callable[[object], Any],
                inherited: Any, default_key: str | None) -> Any:
        """``key`` from this mapping, else the default; missing from both is one problem."""
        if fields.has(key) or default_key is None:
            return fields.take(key, convert)
        fields.used.add(key)
        if inherited is None and fields.valid and default_key not in self.broken_defaults:
            self.ctx.report(fields.child(key),
                            f"required key is missing (and there is no {default_key})")
        return inherited

    def defaults(self, parent: Fields) -> Defaults:
        present, _ = parent.raw("defaults")
        fields = self.section(parent, "defaults", required=False)

        def take(key: str, convert: Callable[[object], Any]) -> Any:
            value = fields.take(key, convert, required=False)
            if fields.has(key) and value is None:
                self.broken_defaults.add(f"defaults.{key}")
            return value

        ramp = take("ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0))
        self.check_ramp(fields.child("ramp_c_per_min"), ramp)
        soak = None
        if fields.has("soak"):
            soak_fields = self.section(fields, "soak")
            soak = self.soak(soak_fields, None, None) if soak_fields.valid else None
            if soak is None:
                self.broken_defaults.update(
                    {"defaults.soak.tolerance_c", "defaults.soak.hold", "defaults.soak.max_wait"})
        else:
            fields.used.add("soak")
        dwell = take("dwell", _duration())
        settle = take("settle", _duration(positive=False))
        accel = take("accel_dps2", quantity(ACCELERATION, above=0.0))
        self.check_accel(fields.child("accel_dps2"), accel)
        station_rate = self.station.gyro.sample_rate_hz if self.station is not None else None
        sample_rate = take("sample_rate_hz", quantity(FREQUENCY, above=0.0))
        if sample_rate is not None and station_rate is not None and sample_rate > station_rate:
            self.ctx.report(fields.child("sample_rate_hz"),
                            f"{format_number(sample_rate)} Hz exceeds the gyro's output rate "
                            f"{format_number(station_rate)} Hz (station {self.station.file}: "
                            f"gyro.sample_rate_hz)")
        if present:
            fields.finish()
        return Defaults(ramp, soak, dwell, settle, accel,
                        sample_rate if sample_rate is not None else station_rate)

    def data_quality(self, parent: Fields) -> DataQuality:
        fields = self.section(parent, "data_quality")
        quality = DataQuality(
            fields.take("max_lost_frame_fraction", number(0.0, above=None, maximum=0.5)),
            fields.take("max_step_repeats", integer(0, 20)),
            fields.take("sf_tolerance_pct", number(0.0, above=0.0, maximum=100.0),
                        required=False, default=5.0),
        )
        fields.finish()
        return quality

    # -- sequence -----------------------------------------------------------------------------
    def temperature_step(self, path: KeyPath, value: object, defaults: Defaults) -> TemperatureStep:
        fields = Fields(self.ctx, path, value, "a temperature step")
        setpoint = fields.take("setpoint_c", quantity(TEMPERATURE, -273.15))
        self.check_setpoint(fields.child("setpoint_c"), setpoint)
        ramp = self.inherit(fields, "ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0),
                            defaults.ramp_c_per_min, "defaults.ramp_c_per_min")
        if fields.has("ramp_c_per_min"):
            self.check_ramp(fields.child("ramp_c_per_min"), ramp)
        if fields.has("soak"):
            soak = self.soak(self.section(fields, "soak"), defaults.soak, "defaults.soak")
        else:
            fields.used.add("soak")
            soak = defaults.soak
            if soak is None and fields.valid and "defaults.soak.hold" not in self.broken_defaults:
                self.ctx.report(fields.child("soak"), "required key is missing (and there is no "
                                "defaults.soak)")
        label = fields.take("label", text, required=False)
        present, raw = fields.raw("tests")
        tests: list[Test] = []
        if present:
            for index, item in enumerate(_list(self.ctx, fields.child("tests"), raw, "tests",
                                               allow_empty=True)):
                test = self.test((*path, "tests", index), item, defaults)
                if test is not None:
                    tests.append(test)
        fields.finish()
        return TemperatureStep(setpoint, ramp, soak, tuple(tests), label)

    def test(self, path: KeyPath, value: object, defaults: Defaults) -> Test | None:
        fields = Fields(self.ctx, path, value, "a test")
        if not fields.valid:
            return None
        kind = fields.take("kind", choice(TEST_KINDS))
        if kind is None:
            fields.used.update(fields.data)   # unknown kind: its keys cannot be judged
            return None
        repeats = fields.take("repeats", integer(1, 100), required=False, default=1)
        label = fields.take("label", text, required=False)
        if kind == "threshold":
            return self.threshold_test(fields, defaults, repeats, label)
        if kind == "rate_limit":
            return self.rate_limit_test(fields, defaults, repeats, label)
        if kind == "frequency_response":
            return self.frequency_response_test(fields, defaults, repeats, label)
        if kind == "magnetic":
            return self.magnetic_test(fields, defaults, repeats, label)
        if kind == "turn_on":
            return self.turn_on_test(fields, repeats, label)
        if kind == "turn_on_repeatability":
            return self.repeatability_test(fields, repeats, label)
        if kind == "tilt_linearity":
            return self.tilt_test(fields, defaults, repeats, label)
        if kind != "sf_sweep":
            # after a sweep the table needs settling before a static hold too, but a
            # procedure that never spins may leave settle out altogether
            settle = fields.take("settle", _duration(positive=False), required=False,
                                 default=defaults.settle_s if defaults.settle_s is not None else 0.0)
            duration_s = fields.take("duration", _duration())
            fields.finish()
            cls = {"static": StaticTest, "allan": AllanTest}.get(kind, TableInterferenceTest)
            return cls(duration_s, settle, repeats, label)

        settle = self.inherit(fields, "settle", _duration(positive=False), defaults.settle_s,
                              "defaults.settle")
        directions = fields.take("directions", choice(DIRECTIONS), required=False, default="both")
        dwell = self.inherit(fields, "dwell", _duration(), defaults.dwell_s, "defaults.dwell")
        accel = self.inherit(fields, "accel_dps2", quantity(ACCELERATION, above=0.0),
                             defaults.accel_dps2, "defaults.accel_dps2")
        if fields.has("accel_dps2"):
            self.check_accel(fields.child("accel_dps2"), accel)
        revolutions = fields.take("min_revolutions", integer(1, 1000), required=False)
        rates, schedule = self.rates(fields)
        fields.finish()
        return SweepTest(rates, schedule, directions, dwell, settle, accel, revolutions,
                         repeats, label)

    def turn_on_test(self, fields: Fields, repeats: int, label: str | None) -> TurnOnTest | None:
        """The station must have a supply that powers the unit (it switches it off and on)."""
        off_s = fields.take("off", _duration())
        duration_s = fields.take("duration", _duration())
        band_dph = fields.take("band_dph", number(above=0.0, maximum=1e6, unit="deg/h"))
        self.needs_supply(fields, "turn_on")
        fields.finish()
        if None in (off_s, duration_s, band_dph):
            return None
        return TurnOnTest(off_s, duration_s, band_dph, repeats, label)

    def repeatability_test(self, fields: Fields, repeats: int,
                           label: str | None) -> TurnOnRepeatabilityTest | None:
        cycles = fields.take("cycles", integer(2, 100))
        off_s = fields.take("off", _duration())
        settle_s = fields.take("settle", _duration(positive=False))
        duration_s = fields.take("duration", _duration())
        self.needs_supply(fields, "turn_on_repeatability")
        fields.finish()
        if None in (cycles, off_s, settle_s, duration_s):
            return None
        return TurnOnRepeatabilityTest(cycles, off_s, settle_s, duration_s, repeats, label)

    def needs_supply(self, fields: Fields, kind: str) -> None:
        station = self.station
        if station is not None and station.supply is None:
            self.ctx.report(fields.child("kind"), f"a {kind} test switches the unit's power; the "
                            f"station {station.file} has no supply: section")

    def magnetic_test(self, fields: Fields, defaults: Defaults, repeats: int,
                      label: str | None) -> MagneticTest | None:
        """|B| must be one the station's coil reaches (coil constant × its max current)."""
        settle = fields.take("settle", _duration(positive=False), required=False,
                             default=defaults.settle_s if defaults.settle_s is not None else 0.0)
        duration_s = fields.take("duration", _duration())
        field_t = fields.take("field_t", number(above=0.0, maximum=1.0, unit="T"))
        station = self.station
        if station is not None and station.coil is None:
            self.ctx.report(fields.child("kind"), f"a magnetic test needs a coil; the station "
                            f"{station.file} has no coil: section")
        elif station is not None and station.coil is not None and field_t is not None \
                and field_t > station.coil.max_field_t:
            coil = station.coil
            self.ctx.report(fields.child("field_t"), f"{format_number(field_t)} T is above what the "
                            f"coil reaches: {format_number(coil.max_field_t)} T ({station.file}: "
                            f"coil.constant_t_per_a {format_number(coil.constant_t_per_a)} × "
                            f"coil.max_current_a {format_number(coil.max_current_a)})")
        fields.finish()
        if None in (settle, duration_s, field_t):
            return None
        return MagneticTest(field_t, duration_s, settle, repeats, label)

    def tilt_test(self, fields: Fields, defaults: Defaults, repeats: int,
                  label: str | None) -> TiltLinearityTest | None:
        """Needs a horizontal table axis and a datagram with the inclinometers (0x93, 0xA7)."""
        settle = fields.take("settle", _duration(positive=False), required=False,
                             default=defaults.settle_s if defaults.settle_s is not None else 0.0)
        dwell = fields.take("dwell", _duration())
        zero_s = fields.take("zero_stability", _duration())
        points = fields.take("points", choice(tuple(TILT_POINTS)))
        station = self.station
        if station is not None and station.table.orientation != "horizontal":
            self.ctx.report(fields.child("kind"), "a tilt_linearity test turns the table as an "
                            f"indexing head through gravity: the station {station.file} must "
                            "declare table.orientation: horizontal")
        if station is not None and not layout_of(station.gyro.datagram).kind.inclination:
            self.ctx.report(fields.child("kind"), f"the station's gyro.datagram "
                            f"0x{station.gyro.datagram:02X} carries no inclinometers; a "
                            "tilt_linearity test needs 0x93 or 0xA7 (TS1524 Table 5-21)")
        fields.finish()
        if None in (settle, dwell, zero_s, points):
            return None
        return TiltLinearityTest(TILT_POINTS[points], points, dwell, settle, zero_s, repeats,
                                 label)

    def threshold_test(self, fields: Fields, defaults: Defaults, repeats: int,
                       label: str | None) -> ThresholdTest:
        settle = self.inherit(fields, "settle", _duration(positive=False), defaults.settle_s,
                              "defaults.settle")
        dwell = self.inherit(fields, "dwell", _duration(), defaults.dwell_s, "defaults.dwell")
        accel = self.inherit(fields, "accel_dps2", quantity(ACCELERATION, above=0.0),
                             defaults.accel_dps2, "defaults.accel_dps2")
        if fields.has("accel_dps2"):
            self.check_accel(fields.child("accel_dps2"), accel)
        confidence = fields.take("confidence", number(above=0.5, maximum=0.999999),
                                 required=False, default=DEFAULT_THRESHOLD_CONFIDENCE)
        fraction = fields.take("max_error_fraction", number(0.0, above=0.0, maximum=1.0),
                               required=False, default=DEFAULT_THRESHOLD_ERROR_FRACTION)
        bases = self.signed_rate_list(fields, "base_rates_dps")
        increments = self.increment_list(fields, bases)
        fields.finish()
        return ThresholdTest(bases, increments, dwell, settle, accel, confidence, fraction,
                             repeats, label)

    def frequency_response_test(self, fields: Fields, defaults: Defaults, repeats: int,
                                label: str | None) -> FrequencyResponseTest:
        """Frequencies increasing, below the sample rate's limit; the sinusoid's peak rate
        and peak acceleration (2πf × amplitude) within the table's limits."""
        amplitude = fields.take("amplitude_dps", quantity(RATE, above=0.0))
        before = len(self.ctx.problems)
        self.check_rate(fields.child("amplitude_dps"), amplitude)
        if len(self.ctx.problems) > before:
            amplitude = None      # refused: its accelerations would only repeat the problem
        cycles = fields.take("cycles", integer(1, 100000), required=False, default=DEFAULT_FR_CYCLES)
        settle_cycles = fields.take("settle_cycles", integer(0, 100000), required=False,
                                    default=DEFAULT_FR_SETTLE_CYCLES)
        min_duration = fields.take("min_duration", _duration(), required=False, default=1.0)
        frequencies = self.frequency_list(fields, defaults.sample_rate_hz)
        phase_at = fields.take("phase_at_hz", quantity(FREQUENCY, above=0.0))
        fields.finish()
        if frequencies and phase_at is not None and not (
                frequencies[0] <= phase_at <= frequencies[-1]):
            self.ctx.report(fields.child("phase_at_hz"), f"{format_number(phase_at)} Hz is outside "
                            f"the swept {format_number(frequencies[0])}..{format_number(frequencies[-1])}"
                            " Hz; the phase is interpolated, never extrapolated")
        if amplitude is not None:
            self.check_peak_accel(fields.child("frequencies_hz"), frequencies, amplitude)
        return FrequencyResponseTest(frequencies, amplitude or 0.0, cycles or DEFAULT_FR_CYCLES,
                                     DEFAULT_FR_SETTLE_CYCLES if settle_cycles is None else settle_cycles,
                                     min_duration or 1.0, phase_at or 0.0, repeats, label)

    def check_peak_accel(self, path: KeyPath, frequencies: tuple[float, ...],
                         amplitude_dps: float) -> None:
        """The sinusoid's peak acceleration 2πf·A within the table limits (the first too high)."""
        limits = [lim for lim in self._limits("table.max_accel_dps2", "table.limits.max_accel_dps2")
                  if lim.value is not None]
        for index, freq in enumerate(frequencies):
            peak = 2.0 * math.pi * freq * amplitude_dps
            over = [lim for lim in limits if peak > lim.value]
            if over:
                tightest = min(over, key=lambda lim: lim.value)
                self.ctx.report((*path, index), f"{format_number(freq)} Hz at "
                                f"{format_number(amplitude_dps)} deg/s peaks at "
                                f"{format_number(peak)} deg/s² (2πf × amplitude), beyond the "
                                f"{tightest.what} {format_number(tightest.value)} deg/s² "
                                f"({tightest.where})")
                return

    def frequency_list(self, fields: Fields, sample_rate_hz: float) -> tuple[float, ...]:
        key = "frequencies_hz"
        present, raw = fields.raw(key)
        if not present:
            if fields.valid:
                self.ctx.report(fields.child(key), "required key is missing")
            return ()
        convert = quantity(FREQUENCY, above=0.0)
        freqs: list[float] = []
        for index, item in enumerate(_list(self.ctx, fields.child(key), raw, key)):
            item_path = (*fields.child(key), index)
            try:
                freq = convert(item)
            except UnitError as error:
                self.ctx.report(item_path, str(error))
                return ()
            if freqs and freq <= freqs[-1]:
                self.ctx.report(item_path, f"{format_number(freq)} Hz is not above the frequency "
                                f"before it ({format_number(freqs[-1])} Hz); the sweep goes up")
                return ()
            if sample_rate_hz and freq * MIN_SAMPLES_PER_PERIOD > sample_rate_hz:
                self.ctx.report(item_path, f"{format_number(freq)} Hz has fewer than "
                                f"{MIN_SAMPLES_PER_PERIOD} samples a period at "
                                f"{format_number(sample_rate_hz)} Hz sampling")
                return ()
            freqs.append(freq)
        if len(freqs) < 2:
            self.ctx.report(fields.child(key), "a sweep needs at least two frequencies")
            return ()
        return tuple(freqs)

    def rate_limit_test(self, fields: Fields, defaults: Defaults, repeats: int,
                        label: str | None) -> RateLimitTest:
        settle = self.inherit(fields, "settle", _duration(positive=False), defaults.settle_s,
                              "defaults.settle")
        dwell = self.inherit(fields, "dwell", _duration(), defaults.dwell_s, "defaults.dwell")
        accel = self.inherit(fields, "accel_dps2", quantity(ACCELERATION, above=0.0),
                             defaults.accel_dps2, "defaults.accel_dps2")
        if fields.has("accel_dps2"):
            self.check_accel(fields.child("accel_dps2"), accel)
        directions = fields.take("directions", choice(DIRECTIONS), required=False, default="both")
        tolerance = fields.take("linearity_tolerance_pct", number(above=0.0, maximum=50.0),
                                required=False, default=DEFAULT_LINEARITY_TOLERANCE_PCT)
        fit_rates = fields.take("fit_rates", integer(1, MAX_LIST), required=False,
                                default=DEFAULT_FIT_RATES)
        present, raw = fields.raw("rates_dps")
        rates: tuple[float, ...] = ()
        if not present:
            if fields.valid:
                self.ctx.report(fields.child("rates_dps"), "required key is missing")
        else:
            rates = self.rate_list(fields.child("rates_dps"), raw)
            for index, (before, after) in enumerate(zip(rates, rates[1:], strict=False)):
                if after <= before:
                    self.ctx.report((*fields.child("rates_dps"), index + 1),
                                    f"{format_number(after)} deg/s is not larger than the rate "
                                    f"before it ({format_number(before)} deg/s); the walk goes up")
                    rates = ()
                    break
        if rates and fit_rates is not None and fit_rates >= len(rates):
            self.ctx.report(fields.child("fit_rates"), f"{fit_rates} fit rates leave none of the "
                            f"{len(rates)} rates_dps to walk beyond the linear fit")
        fields.finish()
        return RateLimitTest(rates, directions, dwell, settle, accel, tolerance, fit_rates,
                             repeats, label)

    def signed_rate_list(self, fields: Fields, key: str) -> tuple[float, ...]:
        """Base rates: signed, 0 allowed, at the table's command resolution, each once."""
        present, raw = fields.raw(key)
        if not present:
            if fields.valid:
                self.ctx.report(fields.child(key), "required key is missing")
            return ()
        convert = quantity(RATE)
        rates: list[float] = []
        for index, item in enumerate(_list(self.ctx, fields.child(key), raw, key)):
            item_path = (*fields.child(key), index)
            try:
                rate = convert(item)
            except UnitError as error:
                self.ctx.report(item_path, str(error))
                continue
            if rate != commanded_rate_dps(rate):
                self.ctx.report(item_path, f"{rate!r} deg/s is finer than a table demand carries "
                                f"({RATE_DECIMALS} decimals); give {commanded_rate_dps(rate)!r}")
                continue
            if rate in rates:
                self.ctx.report(item_path, f"{format_number(rate)} deg/s is listed twice "
                                f"(also {key}[{rates.index(rate)}])")
                continue
            self.check_rate(item_path, abs(rate))
            rates.append(rate)
        return tuple(rates)

    def increment_list(self, fields: Fields, bases: tuple[float, ...]) -> tuple[float, ...]:
        """Increments: positive, strictly increasing, and base + increment within the limits."""
        key = "increments_dps"
        present, raw = fields.raw(key)
        if not present:
            if fields.valid:
                self.ctx.report(fields.child(key), "required key is missing")
            return ()
        increments = self.rate_list(fields.child(key), raw)
        for index, (before, after) in enumerate(zip(increments, increments[1:], strict=False)):
            if after <= before:
                self.ctx.report((*fields.child(key), index + 1),
                                f"{format_number(after)} deg/s is not larger than the increment "
                                f"before it ({format_number(before)} deg/s); list them smallest "
                                "first")
                return ()
        if increments:
            for index, base in enumerate(bases):
                top = abs(base) + increments[-1]
                self.check_rate((*fields.child("base_rates_dps"), index), top)
        return increments

    def rates(self, fields: Fields) -> tuple[tuple[float, ...], RateSchedule | None]:
        has_list, has_schedule = fields.has("rates_dps"), fields.has("schedule")
        fields.used.update({"rates_dps", "schedule"})
        if has_list == has_schedule:
            if fields.valid:
                self.ctx.report(fields.path, "give either rates_dps (a list) or schedule "
                                "(spacing, start_dps, stop_dps, count), not both"
                                if has_list else "missing rates: give rates_dps (a list) or "
                                "schedule (spacing, start_dps, stop_dps, count)")
            return (), None
        if has_list:
            return self.rate_list(fields.child("rates_dps"), fields.data["rates_dps"]), None
        return self.rate_schedule(self.section(fields, "schedule"))

    def rate_list(self, path: KeyPath, raw: object) -> tuple[float, ...]:
        convert = quantity(RATE, above=0.0)
        rates: list[float] = []
        first_index: dict[float, int] = {}
        for index, item in enumerate(_list(self.ctx, path, raw, "rates_dps")):
            item_path = (*path, index)
            try:
                rate = convert(item)
            except UnitError as error:
                message = str(error)
                if "must be greater than 0" in message:
                    message += " (give magnitudes; `directions` sets the signs)"
                self.ctx.report(item_path, message)
                continue
            if rate != commanded_rate_dps(rate):
                self.ctx.report(item_path, f"{rate!r} deg/s is finer than a table demand carries "
                                f"({RATE_DECIMALS} decimals); give {commanded_rate_dps(rate)!r}")
                continue
            if rate in first_index:
                self.ctx.report(item_path, f"{format_number(rate)} deg/s is listed twice "
                                f"(also rates_dps[{first_index[rate]}])")
                continue
            first_index[rate] = index
            self.check_rate(item_path, rate)
            rates.append(rate)
        return tuple(rates)

    def rate_schedule(self, fields: Fields) -> tuple[tuple[float, ...], RateSchedule | None]:
        spacing = fields.take("spacing", choice(SPACINGS))
        start = fields.take("start_dps", quantity(RATE, above=0.0))
        stop = fields.take("stop_dps", quantity(RATE, above=0.0))
        count = fields.take("count", integer(1, MAX_LIST))
        fields.finish()
        if None in (spacing, start, stop, count):
            return (), None
        if stop < start:
            self.ctx.report(fields.child("stop_dps"), f"{format_number(stop)} deg/s is below "
                            f"start_dps {format_number(start)} deg/s")
            return (), None
        if count == 1 and stop != start:
            self.ctx.report(fields.child("count"), "count 1 needs start_dps == stop_dps")
            return (), None
        self.check_rate(fields.child("stop_dps"), stop)
        rates = generate_rates(spacing, start, stop, count)
        if len(set(rates)) != len(rates):
            self.ctx.report(fields.child("count"), f"{count} rates between {format_number(start)} "
                            f"and {format_number(stop)} deg/s repeat at the table's command resolution; "
                            "use fewer")
            return (), None
        return rates, RateSchedule(spacing, start, stop, count)

    # -- acceptance ---------------------------------------------------------------------------
    def acceptance(self, parent: Fields, sequence: tuple[TemperatureStep, ...]) -> tuple[AcceptanceLimit, ...]:
        present, raw = parent.raw("acceptance")
        if not present:
            return ()
        measured = _what_is_measured(sequence)
        limits: list[AcceptanceLimit] = []
        names: dict[str, int] = {}
        for index, item in enumerate(_list(self.ctx, ("acceptance",), raw, "acceptance",
                                           allow_empty=True)):
            path: KeyPath = ("acceptance", index)
            fields = Fields(self.ctx, path, item, "an acceptance limit")
            if not fields.valid:
                continue
            name = fields.take("name", text)
            metric = fields.take("metric", _metric)
            maximum = fields.take("max", number(), required=False)
            minimum = fields.take("min", number(), required=False)
            unit = fields.take("unit", text, required=False)
            rule = fields.take("decision_rule", _decision_rule, required=False)
            fields.finish()
            if fields.has("max") == fields.has("min"):
                self.ctx.report(path, "give exactly one of max or min")
            if maximum is not None and maximum < 0 and metric is not None:
                # every max limit bounds a size, a spread or (signed metrics) a magnitude
                self.ctx.report(fields.child("max"), f"max {format_number(maximum)} can never be "
                                f"met: {metric} is judged by its size, which is never negative")
            if name is not None:
                if name in names:
                    self.ctx.report(fields.child("name"),
                                    f"name {name!r} is used twice (also acceptance[{names[name]}])")
                names.setdefault(name, index)
            if metric is None:
                continue
            spec = METRICS[metric]
            if unit is not None and not units_match(unit, spec):
                self.ctx.report(fields.child("unit"), f"{metric} is in {spec.unit}, not {unit}")
            if unit is None:
                # a limit given without its unit is in the metric's (the report prints it)
                unit = spec.unit if spec.unit is not None else self.output_units
            if spec.needs not in measured and sequence:
                self.ctx.report(fields.child("metric"),
                                f"{metric} cannot be computed: it needs "
                                f"{NEEDS_TEXT[spec.needs]} in the sequence")
            limits.append(AcceptanceLimit(name, metric, maximum, minimum, unit, rule or "simple"))
        return tuple(limits)


def _decision_rule(value: object) -> str:
    if value in ("simple", "guarded"):
        return str(value)
    raise UnitError(f"decision_rule must be simple (value vs limit) or guarded (value ± U "
                    f"inside the limit, ILAC-G8), got {describe(value)}")


def _metric(value: object) -> str:
    if isinstance(value, str) and value in METRICS:
        return value
    close = difflib.get_close_matches(str(value), list(METRICS), n=1) if isinstance(value, str) else []
    hint = f"did you mean {close[0]}? " if close else ""
    shown = repr(value) if isinstance(value, str) else describe(value)
    raise UnitError(f"unknown metric {shown}; {hint}known metrics: {', '.join(METRICS)}")


def _what_is_measured(sequence: tuple[TemperatureStep, ...]) -> set[str]:
    sweep_temps: set[float] = set()
    bias_temps: set[float] = set()
    measured: set[str] = set()
    for step in sequence:
        for test in step.tests:
            if isinstance(test, SweepTest):
                measured.add("sweep")
                sweep_temps.add(step.setpoint_c)
            elif isinstance(test, ThresholdTest):
                measured.add("threshold")
            elif isinstance(test, FrequencyResponseTest):
                measured.add("frequency_response")
            elif isinstance(test, TurnOnTest):
                measured.add("turn_on")
            elif isinstance(test, TurnOnRepeatabilityTest):
                measured.add("turn_on_repeatability")
            elif isinstance(test, RateLimitTest):
                ways = ("positive", "negative") if test.directions == "both" else (test.directions,)
                measured.update(f"rate_limit_{way}" for way in ways)
            else:
                bias_temps.add(step.setpoint_c)
                if isinstance(test, AllanTest):
                    measured.add("allan")
    if len(sweep_temps) >= 2:
        measured.add("sweep_temps")
    if len(bias_temps) >= 2:
        measured.add("bias_temps")
    return measured


def generate_rates(spacing: str, start_dps: float, stop_dps: float, count: int) -> tuple[float, ...]:
    """Rates of a schedule, rounded to what a table command carries (``commanded_rate_dps``)."""
    if count == 1:
        return (commanded_rate_dps(start_dps),)
    rates = []
    for i in range(count):
        fraction = i / (count - 1)
        if spacing == "log":
            rate = start_dps * math.exp(math.log(stop_dps / start_dps) * fraction)
        else:
            rate = start_dps + (stop_dps - start_dps) * fraction
        rates.append(commanded_rate_dps(rate))
    return tuple(rates)
