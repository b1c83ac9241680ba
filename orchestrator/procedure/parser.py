"""The procedure file → :class:`Procedure`, every problem collected before anything moves.

Everything is checked here: the schema, the units, and every setpoint, rate, ramp rate
and acceleration against both the procedure's own safety limits and the station's hard
limits (``envelope.py``). A wrong value at hour 14 of an overnight run costs a night;
here it costs one edit. Every problem is collected and raised together as one
:class:`ProcedureError`, each naming its file, line and field.

Values left out of a test or a temperature step come from ``defaults``; a value that is
in neither place is an error naming both, so no duration is ever silently made up.
The file is read by the one input layer (``gyrocal.inputs``) and walked with the common
schema reader (``gyrocal/schema.py``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gyrocal.inputs import load_yaml, outside_reference
from gyrocal.models.imu_model import Mounting
from gyrocal.orchestrator.procedure.acceptance import read_acceptance
from gyrocal.orchestrator.procedure.envelope import Envelope
from gyrocal.orchestrator.procedure.kinds import read_test
from gyrocal.orchestrator.procedure.reading import Reading, bounded_duration
from gyrocal.orchestrator.procedure.types import (
    DEFAULT_MAX_ETA_S,
    MAX_DECLARED_DURATION_S,
    MOUNTING_ORDERS,
    OUTPUT_UNITS,
    PROCEDURE_VERSION,
    ChamberSafety,
    DataQuality,
    Defaults,
    MountingSpec,
    Procedure,
    Safety,
    SoakCriterion,
    TableSafety,
    TemperatureStep,
    Test,
    UnitUnderTest,
)
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


class _Parser:
    """The top level, the conditions (station, safety, defaults, soak) and the sequence."""

    def __init__(self, ctx: Context, station_path: str | os.PathLike[str] | None) -> None:
        self.ctx = ctx
        self.reading = Reading(ctx)
        self.document = ctx.document
        self.station_path = station_path
        self.station_files: list[Path] = []

    # -- top level ------------------------------------------------------------------------
    def procedure(self, data: object) -> Procedure | None:
        ctx, reading = self.ctx, self.reading
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
        reading.output_units = uut.output_units
        reading.station = self.load_station(fields)
        safety = self.safety_limits(fields)
        reading.envelope = Envelope(ctx, safety, reading.station)
        defaults = self.defaults(fields)
        quality = self.data_quality(fields)
        sequence = self.sequence(fields, defaults)
        acceptance = read_acceptance(reading, fields, sequence)
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
        return Procedure(version, name, description, uut, reading.station, safety, defaults,
                         quality, sequence, acceptance, self.document.file, self.document.path,
                         files, mountings, order,
                         max_duration if max_duration is not None else DEFAULT_MAX_ETA_S,
                         max_duration is not None)

    def sequence(self, fields: Fields, defaults: Defaults) -> tuple[TemperatureStep, ...]:
        present, raw = fields.raw("sequence")
        if not present:
            self.ctx.report(("sequence",), "required key is missing")
            return ()
        return tuple(self.temperature_step(("sequence", index), item, defaults)
                     for index, item in enumerate(self.reading.items(("sequence",), raw,
                                                                     "sequence")))

    def mountings(self, parent: Fields) -> tuple[MountingSpec, ...]:
        present, raw = parent.raw("mountings")
        if not present:
            return ()
        specs: list[MountingSpec] = []
        names: dict[str, int] = {}
        ups: dict[Mounting, int] = {}
        for index, item in enumerate(self.reading.items(("mountings",), raw, "mountings")):
            fields = Fields(self.ctx, ("mountings", index), item, "a mounting")
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

    def unit_under_test(self, parent: Fields) -> UnitUnderTest:
        fields = self.reading.section(parent, "unit_under_test")
        uut = UnitUnderTest(
            fields.take("model", text),
            fields.take("serial", serial_number),
            fields.take("output_units", choice(OUTPUT_UNITS)),
            fields.take("nominal_scale_factor", number(above=0.0)),
        )
        fields.finish()
        return uut

    # -- the station ----------------------------------------------------------------------
    def load_station(self, fields: Fields) -> Station | None:
        """``--station`` if given, else the procedure's ``station:`` (a file or a mapping)."""
        present, raw = fields.raw("station")
        if self.station_path is not None:
            return self._station_file(self.station_path)
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
        # named as the user would (relative to the working folder) when that is the same file
        display = os.path.normpath(os.path.join(os.path.dirname(self.document.file), relative))
        same_file = Path(display).resolve() == target.resolve()
        return self._station_file(display if same_file else target)

    def _station_file(self, path: str | os.PathLike[str]) -> Station | None:
        try:
            station = load_station(path, allow_outside=self.ctx.allow_outside)
        except ProcedureError as error:
            self.ctx.problems.extend(error.problems)
            return None
        if station.path is not None:
            self.station_files.append(station.path)
        return station

    # -- conditions -----------------------------------------------------------------------
    def safety_limits(self, parent: Fields) -> Safety:
        section = self.reading.section
        fields = section(parent, "safety")
        ch = section(fields, "chamber")
        chamber = ChamberSafety(
            ch.take("min_temp_c", quantity(TEMPERATURE, -273.15)),
            ch.take("max_temp_c", quantity(TEMPERATURE, -273.15)),
            ch.take("max_ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0)),
        )
        ch.finish()
        tb = section(fields, "table")
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
        Envelope(self.ctx, None, self.reading.station).check_within_station(
            ch.path, chamber, tb.path, table)
        return Safety(chamber, table)

    def soak(self, fields: Fields, inherited: SoakCriterion | None,
             prefix: str | None) -> SoakCriterion | None:
        """A soak criterion; keys left out come from ``inherited`` (the defaults, at ``prefix``)."""
        def key(name: str) -> str | None:
            return f"{prefix}.{name}" if prefix else None

        inherit = self.reading.inherit
        tolerance = inherit(fields, "tolerance_c", quantity(TEMPERATURE, above=0.0),
                            inherited and inherited.tolerance_c, key("tolerance_c"))
        hold = inherit(fields, "hold", bounded_duration(), inherited and inherited.hold_s,
                       key("hold"))
        max_wait = inherit(fields, "max_wait", bounded_duration(),
                           inherited and inherited.max_wait_s, key("max_wait"))
        fields.finish()
        if None in (tolerance, hold, max_wait):
            return None
        if max_wait < hold:
            self.ctx.report(fields.child("max_wait"),
                            f"max_wait ({format_number(max_wait)} s) is shorter than the hold time "
                            f"({format_number(hold)} s): the soak could never succeed")
        return SoakCriterion(tolerance, hold, max_wait)

    def defaults(self, parent: Fields) -> Defaults:
        reading = self.reading
        present, _ = parent.raw("defaults")
        fields = reading.section(parent, "defaults", required=False)

        def take(key: str, convert: Callable[[object], Any]) -> Any:
            value = fields.take(key, convert, required=False)
            if fields.has(key) and value is None:
                reading.broken_defaults.add(f"defaults.{key}")
            return value

        ramp = take("ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0))
        reading.envelope.check_ramp(fields.child("ramp_c_per_min"), ramp)
        soak = self.default_soak(fields)
        dwell = take("dwell", bounded_duration())
        settle = take("settle", bounded_duration(positive=False))
        accel = take("accel_dps2", quantity(ACCELERATION, above=0.0))
        reading.envelope.check_accel(fields.child("accel_dps2"), accel)
        sample_rate = take("sample_rate_hz", quantity(FREQUENCY, above=0.0))
        station_rate = self.check_sample_rate(fields.child("sample_rate_hz"), sample_rate)
        if present:
            fields.finish()
        return Defaults(ramp, soak, dwell, settle, accel,
                        sample_rate if sample_rate is not None else station_rate)

    def default_soak(self, fields: Fields) -> SoakCriterion | None:
        if not fields.has("soak"):
            fields.used.add("soak")
            return None
        soak_fields = self.reading.section(fields, "soak")
        soak = self.soak(soak_fields, None, None) if soak_fields.valid else None
        if soak is None:
            self.reading.broken_defaults.update(
                {"defaults.soak.tolerance_c", "defaults.soak.hold", "defaults.soak.max_wait"})
        return soak

    def check_sample_rate(self, path: KeyPath, sample_rate_hz: float | None) -> float | None:
        """The station gyro's output rate; a default sample rate above it is reported."""
        station = self.reading.station
        if station is None:
            return None
        station_rate = station.gyro.sample_rate_hz
        if sample_rate_hz is not None and station_rate is not None and sample_rate_hz > station_rate:
            self.ctx.report(path, f"{format_number(sample_rate_hz)} Hz exceeds the gyro's output "
                            f"rate {format_number(station_rate)} Hz (station {station.file}: "
                            f"gyro.sample_rate_hz)")
        return station_rate

    def data_quality(self, parent: Fields) -> DataQuality:
        fields = self.reading.section(parent, "data_quality")
        quality = DataQuality(
            fields.take("max_lost_frame_fraction", number(0.0, above=None, maximum=0.5)),
            fields.take("max_step_repeats", integer(0, 20)),
            fields.take("sf_tolerance_pct", number(0.0, above=0.0, maximum=100.0),
                        required=False, default=5.0),
        )
        fields.finish()
        return quality

    # -- sequence -------------------------------------------------------------------------
    def temperature_step(self, path: KeyPath, value: object, defaults: Defaults) -> TemperatureStep:
        reading = self.reading
        fields = Fields(self.ctx, path, value, "a temperature step")
        setpoint = fields.take("setpoint_c", quantity(TEMPERATURE, -273.15))
        reading.envelope.check_setpoint(fields.child("setpoint_c"), setpoint)
        ramp = reading.inherit(fields, "ramp_c_per_min", quantity(TEMPERATURE_RATE, above=0.0),
                               defaults.ramp_c_per_min, "defaults.ramp_c_per_min")
        if fields.has("ramp_c_per_min"):
            reading.envelope.check_ramp(fields.child("ramp_c_per_min"), ramp)
        if fields.has("soak"):
            soak = self.soak(reading.section(fields, "soak"), defaults.soak, "defaults.soak")
        else:
            fields.used.add("soak")
            soak = defaults.soak
            if soak is None and fields.valid and "defaults.soak.hold" not in reading.broken_defaults:
                self.ctx.report(fields.child("soak"), "required key is missing (and there is no "
                                "defaults.soak)")
        label = fields.take("label", text, required=False)
        present, raw = fields.raw("tests")
        tests: list[Test] = []
        if present:
            for index, item in enumerate(reading.items(fields.child("tests"), raw, "tests",
                                                       allow_empty=True)):
                test = read_test(reading, (*path, "tests", index), item, defaults)
                if test is not None:
                    tests.append(test)
        fields.finish()
        return TemperatureStep(setpoint, ramp, soak, tuple(tests), label)
