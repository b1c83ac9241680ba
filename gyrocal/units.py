"""Durations and physical quantities as operators write them in YAML.

The rule, so nobody has to guess what ``20`` means:

* A **key whose name ends in its unit** (``setpoint_c``, ``rates_dps``,
  ``accel_dps2``, ``ramp_c_per_min``, ``timeout_s``) takes a bare number in that
  unit. It also takes a string with an explicit unit of the same kind
  (``"25 degC"``, ``"0.5 rad/s"``, ``"2 min"``), converted to the key's unit.
* A **key without a unit** (``dwell``, ``settle``, ``duration``, ``hold``,
  ``max_wait``) is a duration and needs a unit: ``90 s``, ``20 min``,
  ``1.5 h``, ``500 ms``, or a sum such as ``1 h 30 min``. A bare ``20`` is
  rejected as ambiguous.

Every error says what was given and what is allowed.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass


class UnitError(ValueError):
    """A value that is not a valid quantity; the message is meant for the operator."""


@dataclass(frozen=True)
class Dimension:
    """One kind of quantity: its canonical unit and the spellings accepted for it."""

    name: str                    # "rate", used in messages
    unit: str                    # canonical unit, the one the key name carries
    factors: dict[str, float]    # accepted unit spelling -> factor to the canonical unit
    offsets: dict[str, float]    # additive offsets after scaling (temperatures only)

    def allowed(self) -> str:
        return ", ".join(self.factors)


DURATION = Dimension(
    "duration", "s",
    {"ms": 1e-3, "s": 1.0, "sec": 1.0, "min": 60.0, "h": 3600.0, "hr": 3600.0, "d": 86400.0},
    {},
)
RATE = Dimension(
    "rate", "deg/s",
    {"deg/s": 1.0, "°/s": 1.0, "dps": 1.0, "deg/h": 1 / 3600, "°/h": 1 / 3600,
     "rad/s": 180.0 / math.pi, "rpm": 6.0},
    {},
)
TEMPERATURE = Dimension(
    "temperature", "°C",
    {"°C": 1.0, "degC": 1.0, "℃": 1.0, "K": 1.0},
    {"K": -273.15},
)
TEMPERATURE_RATE = Dimension(
    "temperature rate", "°C/min",
    {"°C/min": 1.0, "degC/min": 1.0, "°C/s": 60.0, "degC/s": 60.0, "°C/h": 1 / 60, "degC/h": 1 / 60},
    {},
)
ACCELERATION = Dimension(
    "angular acceleration", "deg/s²",
    {"deg/s²": 1.0, "deg/s^2": 1.0, "deg/s2": 1.0, "°/s²": 1.0, "°/s^2": 1.0, "dps2": 1.0,
     "rad/s²": 180.0 / math.pi, "rad/s^2": 180.0 / math.pi},
    {},
)
FREQUENCY = Dimension("frequency", "Hz", {"Hz": 1.0, "kHz": 1e3}, {})

_DIMENSIONS = (DURATION, RATE, TEMPERATURE, TEMPERATURE_RATE, ACCELERATION, FREQUENCY)

_NUMBER = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_QUANTITY_RE = re.compile(rf"^\s*({_NUMBER})\s*(\S.*?)?\s*$")
_DURATION_TERM_RE = re.compile(rf"\s*({_NUMBER})\s*([a-zA-Z]+)\s*")


def _finite(number: float | int | str, given: object) -> float:
    """``float(number)``, refusing inf/nan and integers too large for a float."""
    try:
        result = float(number)
    except OverflowError:
        result = math.inf
    if not math.isfinite(result):
        shown = repr(given) if len(repr(given)) <= 40 else repr(given)[:37] + "..."
        raise UnitError(f"{shown} is not a finite number")
    return result


def as_float(value: int | float) -> float:
    """A YAML number as a finite float, or a :class:`UnitError` that says why not."""
    return _finite(value, value)


def _a(noun: str) -> str:
    return f"an {noun}" if noun[0] in "aeiou" else f"a {noun}"


def is_number(value: object) -> bool:
    """True for int/float but not bool (YAML ``true`` is an int in Python)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def _dimension_of(unit: str) -> Dimension | None:
    for dimension in _DIMENSIONS:
        if unit in dimension.factors:
            return dimension
    return None


def parse_quantity(value: object, dimension: Dimension) -> float:
    """A number in the dimension's canonical unit, from a bare number or ``"<number> <unit>"``.

    Bare numbers are taken to be in the canonical unit: only call this for keys
    whose name carries that unit.
    """
    if is_number(value):
        return _finite(value, value)
    if not isinstance(value, str):
        raise UnitError(
            f"expected a number in {dimension.unit} or a string such as "
            f"'10 {dimension.unit}', got {describe(value)}"
        )
    match = _QUANTITY_RE.match(value)
    if match is None:
        raise UnitError(
            f"{value!r} is not {_a(dimension.name)}; write a number with a unit, "
            f"e.g. '10 {dimension.unit}' (units: {dimension.allowed()})"
        )
    number = _finite(match.group(1), value)
    unit = match.group(2)
    if unit is None:
        return number
    if unit in dimension.factors:
        return _finite(number * dimension.factors[unit] + dimension.offsets.get(unit, 0.0), value)
    other = _dimension_of(unit)
    if other is not None:
        raise UnitError(f"{value!r} is {_a(other.name)}, expected {_a(dimension.name)} ({dimension.unit})")
    raise UnitError(f"unknown unit {unit!r} in {value!r}; use one of {dimension.allowed()}")


def parse_duration_s(value: object, *, bare_seconds: bool = False) -> float:
    """Seconds from ``"90 s"``, ``"20 min"``, ``"1.5 h"``, ``"500 ms"``, ``"1 h 30 min"``.

    A bare number is accepted only with ``bare_seconds`` (keys named ``*_s``);
    elsewhere ``20`` could mean seconds, minutes or hours and is refused.
    """
    if is_number(value):
        if not bare_seconds:
            raise UnitError(_ambiguous(value))
        seconds = _finite(value, value)
    elif isinstance(value, str):
        seconds = _parse_duration_text(value, bare_seconds)
    else:
        raise UnitError(
            f"expected a duration such as '90 s', '20 min' or '1.5 h', got {describe(value)}"
        )
    if seconds < 0:
        raise UnitError(f"{value!r}: a duration cannot be negative")
    return seconds


def _parse_duration_text(text: str, bare_seconds: bool) -> float:
    stripped = text.strip()
    if re.fullmatch(_NUMBER, stripped):
        if bare_seconds:
            return _finite(stripped, text)
        raise UnitError(_ambiguous(stripped))
    whole = _QUANTITY_RE.match(stripped)
    other = _dimension_of(whole.group(2)) if whole and whole.group(2) else None
    if other is not None and other is not DURATION:
        raise UnitError(f"{text!r} is {_a(other.name)}, expected a duration")
    position = 0
    total = 0.0
    terms = 0
    for match in _DURATION_TERM_RE.finditer(stripped):
        if match.start() != position:
            break
        number, unit = match.group(1), match.group(2)
        if unit not in DURATION.factors:
            other = _dimension_of(unit)
            if other is not None:
                raise UnitError(f"{text!r} is {_a(other.name)}, expected a duration")
            raise UnitError(f"unknown time unit {unit!r} in {text!r}; use one of {DURATION.allowed()}")
        total += _finite(number, text) * DURATION.factors[unit]
        position = match.end()
        terms += 1
    _finite(total, text)
    if terms == 0 or position != len(stripped):
        raise UnitError(
            f"{text!r} is not a duration; write e.g. '90 s', '20 min', '1.5 h', '500 ms' "
            f"or '1 h 30 min' (units: {DURATION.allowed()})"
        )
    return total


def shown(value: object) -> str:
    """A value as an operator would recognise it, never thousands of digits long."""
    text = format(value, "g") if isinstance(value, float) else str(value)
    return text if len(text) <= 24 else text[:21] + "..."


def _ambiguous(given: object) -> str:
    number = shown(given)
    return (
        f"{number} is ambiguous: give a unit, e.g. '{number} s', '{number} min' or "
        f"'{number} h' (units: {DURATION.allowed()}; bare numbers only in keys ending in _s)"
    )


def describe(value: object) -> str:
    """``list [1, 2]``-style description of a wrong value for an error message."""
    kind = {dict: "a mapping", list: "a list", str: "the text", bool: "the boolean",
            type(None): "nothing (null)"}.get(type(value))
    if value is None:
        return "nothing (null)"
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{kind} {text}" if kind else f"{type(value).__name__} {text}"


def format_hms(seconds: float | None, *, live: bool = False) -> str:
    """``H:MM:SS``, the one clock format of plans, progress lines, status and the console.

    Plans print the nearest second (``0:30:00``; a sum of float durations such as
    1799.9999 s is half an hour). ``live`` counters (elapsed, ETA, event age) show the
    whole seconds that have passed, never below zero, with two hour digits so the line
    does not shift as it ticks (``00:30:00``); ``None`` (not known yet) is ``--:--:--``.
    """
    if seconds is None:
        return "--:--:--"
    whole = max(0, int(seconds)) if live else int(round(seconds))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours:02d}:{minutes:02d}:{secs:02d}" if live else f"{hours:d}:{minutes:02d}:{secs:02d}"


def format_duration(seconds: float) -> str:
    """Readable duration for plans: ``45 s``, ``12 min 30 s``, ``18 h 05 min``."""
    if seconds < 60:
        return f"{seconds:.3g} s" if seconds < 10 else f"{seconds:.0f} s"
    total = round(seconds)
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours} h {minutes:02d} min"
    return f"{minutes} min {secs:02d} s" if secs else f"{minutes} min"


def format_number(value: float) -> str:
    """Numbers in messages: as short as exact (``500``, ``-40``, ``0.05``)."""
    return f"{value:g}"
