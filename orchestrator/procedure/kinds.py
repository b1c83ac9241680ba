"""One reader per test kind: a test's keys, their defaults, and what the station must have.

:func:`read_test` reads the keys every test has (``kind``, ``repeats``, ``label``) and hands
the rest to the reader of its :class:`TestKind`. Each reader returns ``None`` when a value
it needs was wrong (already reported), never a half-built test.
"""

from __future__ import annotations

from collections.abc import Callable

from gyrocal.instruments.gyro.datagram_types import layout_of
from gyrocal.orchestrator.procedure.rates import (
    increasing_rates,
    increment_list,
    signed_rate_list,
    sweep_rates,
)
from gyrocal.orchestrator.procedure.reading import Reading, bounded_duration
from gyrocal.orchestrator.procedure.types import (
    DEFAULT_FIT_RATES,
    DEFAULT_FR_CYCLES,
    DEFAULT_FR_SETTLE_CYCLES,
    DEFAULT_LINEARITY_TOLERANCE_PCT,
    DEFAULT_THRESHOLD_CONFIDENCE,
    DEFAULT_THRESHOLD_ERROR_FRACTION,
    DIRECTIONS,
    MAX_LIST,
    MIN_SAMPLES_PER_PERIOD,
    TEST_KINDS,
    TILT_POINTS,
    AllanTest,
    Defaults,
    FrequencyResponseTest,
    MagneticTest,
    RateLimitTest,
    StaticTest,
    SweepTest,
    TableInterferenceTest,
    Test,
    TestKind,
    ThresholdTest,
    TiltLinearityTest,
    TurnOnRepeatabilityTest,
    TurnOnTest,
)
from gyrocal.problems import KeyPath
from gyrocal.schema import Fields, choice, integer, number, quantity, text
from gyrocal.units import ACCELERATION, FREQUENCY, RATE, UnitError, format_number

#: what every kind reader is given: the reading, the test's keys, the defaults, repeats, label
KindReader = Callable[[Reading, Fields, Defaults, int, str | None], Test | None]


def read_test(reading: Reading, path: KeyPath, value: object, defaults: Defaults) -> Test | None:
    """One entry of a temperature step's ``tests:``."""
    fields = Fields(reading.ctx, path, value, "a test")
    if not fields.valid:
        return None
    kind = fields.take("kind", choice(TEST_KINDS))
    if kind is None:
        fields.used.update(fields.data)   # unknown kind: its keys cannot be judged
        return None
    repeats = fields.take("repeats", integer(1, 100), required=False, default=1)
    label = fields.take("label", text, required=False)
    return READERS[TestKind(kind)](reading, fields, defaults, repeats, label)


# -- shared keys ---------------------------------------------------------------------------

def _optional_settle(fields: Fields, defaults: Defaults) -> float | None:
    """A test that never spins may leave settle out altogether (0 s unless defaulted)."""
    return fields.take("settle", bounded_duration(positive=False), required=False,
                       default=defaults.settle_s if defaults.settle_s is not None else 0.0)


def _motion(reading: Reading, fields: Fields,
            defaults: Defaults) -> tuple[float | None, float | None, float | None]:
    """(settle_s, dwell_s, accel_dps2) of a test that turns the table, inherited if left out."""
    settle = reading.inherit(fields, "settle", bounded_duration(positive=False),
                             defaults.settle_s, "defaults.settle")
    dwell = reading.inherit(fields, "dwell", bounded_duration(), defaults.dwell_s,
                            "defaults.dwell")
    accel = reading.inherit(fields, "accel_dps2", quantity(ACCELERATION, above=0.0),
                            defaults.accel_dps2, "defaults.accel_dps2")
    if fields.has("accel_dps2"):
        reading.envelope.check_accel(fields.child("accel_dps2"), accel)
    return settle, dwell, accel


# -- at rest -------------------------------------------------------------------------------

def _at_rest(cls: type[StaticTest | AllanTest | TableInterferenceTest]) -> KindReader:
    """static, allan and table_interference: a duration at rest after a settle."""
    def read(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
             label: str | None) -> Test:
        # after a sweep the table needs settling before a static hold too, but a
        # procedure that never spins may leave settle out altogether
        settle = _optional_settle(fields, defaults)
        duration_s = fields.take("duration", bounded_duration())
        fields.finish()
        return cls(duration_s, settle, repeats, label)
    return read


def _needs_supply(reading: Reading, fields: Fields, kind: TestKind) -> None:
    station = reading.station
    if station is not None and station.supply is None:
        reading.report(fields.child("kind"), f"a {kind} test switches the unit's power; the "
                       f"station {station.file} has no supply: section")


def _turn_on(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
             label: str | None) -> TurnOnTest | None:
    """The station must have a supply that powers the unit (it switches it off and on)."""
    off_s = fields.take("off", bounded_duration())
    duration_s = fields.take("duration", bounded_duration())
    band_dph = fields.take("band_dph", number(above=0.0, maximum=1e6, unit="deg/h"))
    _needs_supply(reading, fields, TestKind.TURN_ON)
    fields.finish()
    if None in (off_s, duration_s, band_dph):
        return None
    return TurnOnTest(off_s, duration_s, band_dph, repeats, label)


def _repeatability(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
                   label: str | None) -> TurnOnRepeatabilityTest | None:
    cycles = fields.take("cycles", integer(2, 100))
    off_s = fields.take("off", bounded_duration())
    settle_s = fields.take("settle", bounded_duration(positive=False))
    duration_s = fields.take("duration", bounded_duration())
    _needs_supply(reading, fields, TestKind.TURN_ON_REPEATABILITY)
    fields.finish()
    if None in (cycles, off_s, settle_s, duration_s):
        return None
    return TurnOnRepeatabilityTest(cycles, off_s, settle_s, duration_s, repeats, label)


def _magnetic(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
              label: str | None) -> MagneticTest | None:
    """|B| must be one the station's coil reaches (coil constant × its max current)."""
    settle = _optional_settle(fields, defaults)
    duration_s = fields.take("duration", bounded_duration())
    field_t = fields.take("field_t", number(above=0.0, maximum=1.0, unit="T"))
    station = reading.station
    if station is not None and station.coil is None:
        reading.report(fields.child("kind"), f"a magnetic test needs a coil; the station "
                       f"{station.file} has no coil: section")
    elif station is not None and station.coil is not None and field_t is not None \
            and field_t > station.coil.max_field_t:
        coil = station.coil
        reading.report(fields.child("field_t"), f"{format_number(field_t)} T is above what the "
                       f"coil reaches: {format_number(coil.max_field_t)} T ({station.file}: "
                       f"coil.constant_t_per_a {format_number(coil.constant_t_per_a)} × "
                       f"coil.max_current_a {format_number(coil.max_current_a)})")
    fields.finish()
    if None in (settle, duration_s, field_t):
        return None
    return MagneticTest(field_t, duration_s, settle, repeats, label)


def _tilt(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
          label: str | None) -> TiltLinearityTest | None:
    """Needs a horizontal table axis and a datagram with the inclinometers (0x93, 0xA7)."""
    settle = _optional_settle(fields, defaults)
    dwell = fields.take("dwell", bounded_duration())
    zero_s = fields.take("zero_stability", bounded_duration())
    points = fields.take("points", choice(tuple(TILT_POINTS)))
    station = reading.station
    if station is not None and station.table.orientation != "horizontal":
        reading.report(fields.child("kind"), "a tilt_linearity test turns the table as an "
                       f"indexing head through gravity: the station {station.file} must "
                       "declare table.orientation: horizontal")
    if station is not None and not layout_of(station.gyro.datagram).kind.inclination:
        reading.report(fields.child("kind"), f"the station's gyro.datagram "
                       f"0x{station.gyro.datagram:02X} carries no inclinometers; a "
                       "tilt_linearity test needs 0x93 or 0xA7 (TS1524 Table 5-21)")
    fields.finish()
    if None in (settle, dwell, zero_s, points):
        return None
    return TiltLinearityTest(TILT_POINTS[points], points, dwell, settle, zero_s, repeats, label)


# -- turning -------------------------------------------------------------------------------

def _sweep(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
           label: str | None) -> SweepTest:
    settle = reading.inherit(fields, "settle", bounded_duration(positive=False),
                             defaults.settle_s, "defaults.settle")
    directions = fields.take("directions", choice(DIRECTIONS), required=False, default="both")
    dwell = reading.inherit(fields, "dwell", bounded_duration(), defaults.dwell_s,
                            "defaults.dwell")
    accel = reading.inherit(fields, "accel_dps2", quantity(ACCELERATION, above=0.0),
                            defaults.accel_dps2, "defaults.accel_dps2")
    if fields.has("accel_dps2"):
        reading.envelope.check_accel(fields.child("accel_dps2"), accel)
    revolutions = fields.take("min_revolutions", integer(1, 1000), required=False)
    rates, schedule = sweep_rates(reading, fields)
    fields.finish()
    return SweepTest(rates, schedule, directions, dwell, settle, accel, revolutions,
                     repeats, label)


def _threshold(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
               label: str | None) -> ThresholdTest:
    settle, dwell, accel = _motion(reading, fields, defaults)
    confidence = fields.take("confidence", number(above=0.5, maximum=0.999999),
                             required=False, default=DEFAULT_THRESHOLD_CONFIDENCE)
    fraction = fields.take("max_error_fraction", number(0.0, above=0.0, maximum=1.0),
                           required=False, default=DEFAULT_THRESHOLD_ERROR_FRACTION)
    bases = signed_rate_list(reading, fields, "base_rates_dps")
    increments = increment_list(reading, fields, bases)
    fields.finish()
    return ThresholdTest(bases, increments, dwell, settle, accel, confidence, fraction,
                         repeats, label)


def _rate_limit(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
                label: str | None) -> RateLimitTest:
    settle, dwell, accel = _motion(reading, fields, defaults)
    directions = fields.take("directions", choice(DIRECTIONS), required=False, default="both")
    tolerance = fields.take("linearity_tolerance_pct", number(above=0.0, maximum=50.0),
                            required=False, default=DEFAULT_LINEARITY_TOLERANCE_PCT)
    fit_rates = fields.take("fit_rates", integer(1, MAX_LIST), required=False,
                            default=DEFAULT_FIT_RATES)
    rates = increasing_rates(reading, fields, "rates_dps", "rate", "the walk goes up")
    if rates and fit_rates is not None and fit_rates >= len(rates):
        reading.report(fields.child("fit_rates"), f"{fit_rates} fit rates leave none of the "
                       f"{len(rates)} rates_dps to walk beyond the linear fit")
    fields.finish()
    return RateLimitTest(rates, directions, dwell, settle, accel, tolerance, fit_rates,
                         repeats, label)


def _frequency_response(reading: Reading, fields: Fields, defaults: Defaults, repeats: int,
                        label: str | None) -> FrequencyResponseTest:
    """Frequencies increasing, below the sample rate's limit; the sinusoid's peak rate
    and peak acceleration (2πf × amplitude) within the table's limits."""
    amplitude = fields.take("amplitude_dps", quantity(RATE, above=0.0))
    before = len(reading.ctx.problems)
    reading.envelope.check_rate(fields.child("amplitude_dps"), amplitude)
    if len(reading.ctx.problems) > before:
        amplitude = None      # refused: its accelerations would only repeat the problem
    cycles = fields.take("cycles", integer(1, 100000), required=False, default=DEFAULT_FR_CYCLES)
    settle_cycles = fields.take("settle_cycles", integer(0, 100000), required=False,
                                default=DEFAULT_FR_SETTLE_CYCLES)
    min_duration = fields.take("min_duration", bounded_duration(), required=False, default=1.0)
    frequencies = _frequency_list(reading, fields, defaults.sample_rate_hz)
    phase_at = fields.take("phase_at_hz", quantity(FREQUENCY, above=0.0))
    fields.finish()
    if frequencies and phase_at is not None and not (
            frequencies[0] <= phase_at <= frequencies[-1]):
        reading.report(fields.child("phase_at_hz"), f"{format_number(phase_at)} Hz is outside "
                       f"the swept {format_number(frequencies[0])}..{format_number(frequencies[-1])}"
                       " Hz; the phase is interpolated, never extrapolated")
    if amplitude is not None:
        reading.envelope.check_peak_accel(fields.child("frequencies_hz"), frequencies, amplitude)
    return FrequencyResponseTest(frequencies, amplitude or 0.0, cycles or DEFAULT_FR_CYCLES,
                                 DEFAULT_FR_SETTLE_CYCLES if settle_cycles is None else settle_cycles,
                                 min_duration or 1.0, phase_at or 0.0, repeats, label)


def _frequency_problem(freq: float, previous: float | None, sample_rate_hz: float) -> str | None:
    if previous is not None and freq <= previous:
        return (f"{format_number(freq)} Hz is not above the frequency before it "
                f"({format_number(previous)} Hz); the sweep goes up")
    if sample_rate_hz and freq * MIN_SAMPLES_PER_PERIOD > sample_rate_hz:
        return (f"{format_number(freq)} Hz has fewer than {MIN_SAMPLES_PER_PERIOD} samples a "
                f"period at {format_number(sample_rate_hz)} Hz sampling")
    return None


def _frequency_list(reading: Reading, fields: Fields, sample_rate_hz: float) -> tuple[float, ...]:
    """At least two, increasing, each with enough samples a period; () after the first bad."""
    key = "frequencies_hz"
    present, raw = reading.required_raw(fields, key)
    if not present:
        return ()
    convert = quantity(FREQUENCY, above=0.0)
    freqs: list[float] = []
    for index, item in enumerate(reading.items(fields.child(key), raw, key)):
        item_path = (*fields.child(key), index)
        try:
            freq = convert(item)
        except UnitError as error:
            reading.report(item_path, str(error))
            return ()
        problem = _frequency_problem(freq, freqs[-1] if freqs else None, sample_rate_hz)
        if problem is not None:
            reading.report(item_path, problem)
            return ()
        freqs.append(freq)
    if len(freqs) < 2:
        reading.report(fields.child(key), "a sweep needs at least two frequencies")
        return ()
    return tuple(freqs)


READERS: dict[TestKind, KindReader] = {
    TestKind.STATIC: _at_rest(StaticTest),
    TestKind.ALLAN: _at_rest(AllanTest),
    TestKind.TABLE_INTERFERENCE: _at_rest(TableInterferenceTest),
    TestKind.SF_SWEEP: _sweep,
    TestKind.THRESHOLD: _threshold,
    TestKind.RATE_LIMIT: _rate_limit,
    TestKind.FREQUENCY_RESPONSE: _frequency_response,
    TestKind.MAGNETIC: _magnetic,
    TestKind.TILT_LINEARITY: _tilt,
    TestKind.TURN_ON: _turn_on,
    TestKind.TURN_ON_REPEATABILITY: _repeatability,
}
