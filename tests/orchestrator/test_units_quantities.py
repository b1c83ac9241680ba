"""Durations and quantities as operators write them: accepted spellings and refusals."""

import math

import pytest

from gyrocal.units import (
    ACCELERATION,
    RATE,
    TEMPERATURE,
    TEMPERATURE_RATE,
    UnitError,
    format_duration,
    format_hms,
    parse_duration_s,
    parse_quantity,
)

pytestmark = pytest.mark.timeout(30)


@pytest.mark.parametrize(
    ("text", "seconds"),
    [("90 s", 90.0), ("20 min", 1200.0), ("1.5 h", 5400.0), ("8 h", 28800.0), ("500 ms", 0.5),
     ("1 h 30 min", 5400.0), ("2min30s", 150.0), ("1e3 s", 1000.0), ("0.25 d", 21600.0)],
)
def test_durations_with_units(text, seconds):
    assert parse_duration_s(text) == pytest.approx(seconds)


@pytest.mark.parametrize("value", [20, 20.0, "20", " 20 "])
def test_a_bare_duration_is_ambiguous_and_the_error_says_what_is_allowed(value):
    with pytest.raises(UnitError) as error:
        parse_duration_s(value)
    message = str(error.value)
    assert "ambiguous" in message and "'20 s'" in message and "'20 min'" in message
    assert "ms, s, sec, min, h" in message


def test_bare_seconds_only_where_the_key_says_seconds():
    assert parse_duration_s(1.5, bare_seconds=True) == 1.5
    assert parse_duration_s("2", bare_seconds=True) == 2.0
    assert parse_duration_s("2 min", bare_seconds=True) == 120.0


@pytest.mark.parametrize(
    ("value", "fragment"),
    [("3 fortnights", "unknown time unit 'fortnights'"),
     ("20 deg/s", "'20 deg/s' is a rate, expected a duration"),
     ("-5 s", "cannot be negative"),
     ("2 h x", "is not a duration"),
     (True, "got the boolean True"),
     ([1], "got a list [1]"),
     (None, "got nothing (null)"),
     ("1e400 s", "is not a finite number")],
)
def test_bad_durations_say_why(value, fragment):
    with pytest.raises(UnitError, match=None) as error:
        parse_duration_s(value)
    assert fragment in str(error.value)


def test_quantities_convert_to_the_keys_unit():
    # independent references: math.degrees, the Kelvin offset, 1 rpm = 6 deg/s
    assert parse_quantity("1 rad/s", RATE) == pytest.approx(math.degrees(1.0))
    assert parse_quantity("10 rpm", RATE) == pytest.approx(60.0)
    assert parse_quantity("3600 deg/h", RATE) == pytest.approx(1.0)
    assert parse_quantity("298.15 K", TEMPERATURE) == pytest.approx(25.0)
    assert parse_quantity("25 °C", TEMPERATURE) == parse_quantity("25degC", TEMPERATURE) == 25.0
    assert parse_quantity("0.05 °C/s", TEMPERATURE_RATE) == pytest.approx(3.0)
    assert parse_quantity("1 rad/s^2", ACCELERATION) == pytest.approx(math.degrees(1.0))
    assert parse_quantity(-40, TEMPERATURE) == -40.0


@pytest.mark.parametrize(
    ("value", "dimension", "message"),
    [("70 °F", TEMPERATURE, "unknown unit '°F' in '70 °F'; use one of °C, degC, ℃, K"),
     ("5 min", TEMPERATURE, "'5 min' is a duration, expected a temperature (°C)"),
     ("100 deg/s", TEMPERATURE, "'100 deg/s' is a rate, expected a temperature (°C)"),
     ("fast", RATE, "'fast' is not a rate; write a number with a unit, e.g. '10 deg/s' "
                    "(units: deg/s, °/s, dps, deg/h, °/h, rad/s, rpm)"),
     (True, RATE, "expected a number in deg/s or a string such as '10 deg/s', got the boolean True"),
     (10**400, RATE, "is not a finite number"),
     (float("nan"), RATE, "nan is not a finite number")],
)
def test_bad_quantities_say_why(value, dimension, message):
    with pytest.raises(UnitError) as error:
        parse_quantity(value, dimension)
    assert message in str(error.value)


def test_format_hms_plan_times_round_to_the_nearest_second():
    assert format_hms(1799.9999) == "0:30:00"      # a sum of float durations is half an hour
    assert format_hms(16 * 3600 + 5 * 60 + 20.4) == "16:05:20"
    assert format_hms(100 * 3600) == "100:00:00"


def test_format_hms_live_counters_count_whole_seconds_never_below_zero():
    assert format_hms(3 * 3600 + 5.9, live=True) == "03:00:05"
    assert format_hms(-2.0, live=True) == "00:00:00"
    assert format_hms(None, live=True) == "--:--:--"


def test_format_duration_reads_like_a_person_would_write_it():
    assert format_duration(5.5) == "5.5 s"
    assert format_duration(45) == "45 s"
    assert format_duration(125) == "2 min 05 s"
    assert format_duration(1200) == "20 min"
    assert format_duration(16 * 3600 + 5 * 60 + 20) == "16 h 05 min"


def test_huge_integers_are_refused_without_printing_all_their_digits():
    with pytest.raises(UnitError) as error:
        parse_duration_s(10**400)
    assert "ambiguous" in str(error.value) and len(str(error.value)) < 250
    with pytest.raises(UnitError, match="is not a finite number"):
        parse_duration_s(10**400, bare_seconds=True)
