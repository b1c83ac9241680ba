"""A small schema reader that collects every problem instead of stopping at the first.

Station and procedure parsers walk the loaded data with :class:`Fields`: each
``take`` converts one key and, when the value is wrong, records a
:class:`Problem` at that key's line and returns ``None`` so parsing goes on.
``finish`` then reports unknown keys (with a "did you mean"). Callers must
treat a ``None`` from ``take`` as "already reported" and skip cross-checks
that need it; the half-built result is never returned, because the loader
raises once any problem was recorded.
"""

from __future__ import annotations

import datetime as dt
import difflib
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

from gyrocal.inputs import YamlDocument
from gyrocal.problems import KeyPath, Problem
from gyrocal.units import (
    Dimension,
    UnitError,
    as_float,
    describe,
    format_number,
    is_number,
    parse_duration_s,
    parse_quantity,
    shown,
)

T = TypeVar("T")
Converter = Callable[[object], Any]


class Context:
    """The document being read and the problems found so far."""

    def __init__(self, document: YamlDocument, problems: list[Problem] | None = None, *,
                 allow_outside: bool = False) -> None:
        self.document = document
        self.problems: list[Problem] = problems if problems is not None else []
        #: files named in the document may lie outside its folder/project (--allow-outside-paths)
        self.allow_outside = allow_outside

    def report(self, path: KeyPath, message: str) -> None:
        self.problems.append(self.document.problem(path, message))


def _shape(value: object) -> str:
    """What a document is, without a word of what it says."""
    if isinstance(value, str):
        return f"a plain text of {len(value)} characters (is this the file you meant?)"
    if isinstance(value, list):
        return f"a list of {len(value)} entries"
    return "nothing (an empty file)" if value is None else f"a single {type(value).__name__}"


class Fields:
    """The keys of one mapping, read one by one; what is left over is unknown."""

    def __init__(self, ctx: Context, path: KeyPath, value: object, what: str) -> None:
        self.ctx = ctx
        self.path = path
        self.valid = isinstance(value, dict)
        self.data: dict[str, Any] = value if isinstance(value, dict) else {}
        self.used: set[str] = set()
        if not self.valid:
            # A whole file that is not a mapping is most likely not the file the user meant
            # (`station: /etc/passwd`): name its shape, never echo its contents.
            got = describe(value) if path else _shape(value)
            ctx.report(path, f"{what} must be a mapping of keys, got {got}")

    def has(self, key: str) -> bool:
        return key in self.data

    def child(self, key: str) -> KeyPath:
        return (*self.path, key)

    def take(self, key: str, convert: Converter, *, required: bool = True, default: Any = None) -> Any:
        """The converted value of ``key``; on any problem, report it and return ``None``."""
        self.used.add(key)
        if key not in self.data:
            if required and self.valid:
                self.ctx.report(self.child(key), "required key is missing")
                return None
            return default
        try:
            return convert(self.data[key])
        except UnitError as error:
            self.ctx.report(self.child(key), str(error))
            return None

    def raw(self, key: str) -> tuple[bool, Any]:
        """Presence and raw value, for nested structures parsed by the caller."""
        self.used.add(key)
        return key in self.data, self.data.get(key)

    def finish(self) -> None:
        allowed = sorted(self.used)
        for key in self.data:
            if key in self.used:
                continue
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            self.ctx.report(
                self.child(key), f"unknown key '{key}'{hint} (allowed here: {', '.join(allowed)})"
            )


# -- converters: value -> typed value, or UnitError with an operator-facing message ----

def text(value: object) -> str:
    if not isinstance(value, str) or not value.strip():
        raise UnitError(f"expected non-empty text, got {describe(value)}")
    return value.strip()


def file_name(value: object) -> str:
    """A file path named inside a procedure or station: text with no NUL or control character.

    The operating system cannot open such a name (Python raises a bare
    ``ValueError: embedded null byte``); here it is an error at its key and line.
    """
    name = text(value)
    bad = next((c for c in name if ord(c) < 32 or ord(c) == 127), None)
    if bad is not None:
        raise UnitError(f"a file name cannot hold the control character {bad!r}, got {name!r}")
    return name


def serial_number(value: object) -> str:
    """Serials are often all digits; YAML reads ``12345`` as a number, so take it as text."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    serial = text(value)
    if len(serial) > MAX_SERIAL_CHARS or any(not c.isprintable() for c in serial):
        raise UnitError(f"a serial number is at most {MAX_SERIAL_CHARS} printable characters, "
                        f"got {describe(value)}")
    return serial


#: Longer than any maker's serial; what a serial *means* ("5 parsecs") cannot be checked
#: here: the instrument's own report (*IDN?, serial registers) is what it is compared with.
MAX_SERIAL_CHARS = 64


def boolean(value: object) -> bool:
    if not isinstance(value, bool):
        raise UnitError(f"expected true or false, got {describe(value)}")
    return value


def integer(minimum: int | None = None, maximum: int | None = None) -> Converter:
    def convert(value: object) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise UnitError(f"expected a whole number, got {describe(value)}")
        if minimum is not None and value < minimum:
            raise UnitError(f"{shown(value)} is below the minimum {minimum}")
        if maximum is not None and value > maximum:
            raise UnitError(f"{shown(value)} is above the maximum {maximum}")
        return value
    return convert


def number(
    minimum: float | None = None,
    maximum: float | None = None,
    *,
    above: float | None = None,
    unit: str = "",
) -> Converter:
    """A plain finite number, e.g. a scale factor or a latitude."""
    def convert(value: object) -> float:
        if not is_number(value):
            raise UnitError(f"expected a number, got {describe(value)}")
        result = as_float(value)
        _check_range(result, minimum, maximum, unit, above=above)
        return result
    return convert


def quantity(
    dimension: Dimension,
    minimum: float | None = None,
    maximum: float | None = None,
    *,
    above: float | None = None,
) -> Converter:
    """A number in the key's unit, or a string with any unit of the same dimension."""
    def convert(value: object) -> float:
        result = parse_quantity(value, dimension)
        _check_range(result, minimum, maximum, dimension.unit, above=above)
        return result
    return convert


def duration(*, positive: bool = True, bare_seconds: bool = False) -> Converter:
    def convert(value: object) -> float:
        seconds = parse_duration_s(value, bare_seconds=bare_seconds)
        if positive and seconds <= 0:
            raise UnitError(f"{value!r}: must be longer than zero")
        return seconds
    return convert


def choice(options: Iterable[str]) -> Converter:
    allowed = tuple(options)

    def convert(value: object) -> str:
        if not isinstance(value, str) or value not in allowed:
            raise UnitError(f"expected one of {', '.join(allowed)}, got {describe(value)}")
        return value
    return convert


def date(value: object) -> dt.date:
    if isinstance(value, dt.datetime):
        return value.date()
    if isinstance(value, dt.date):
        return value
    if isinstance(value, str):
        try:
            return dt.date.fromisoformat(value.strip())
        except ValueError:
            pass
    raise UnitError(f"expected a date YYYY-MM-DD, got {describe(value)}")


def _check_range(
    value: float,
    minimum: float | None,
    maximum: float | None,
    unit: str,
    *,
    above: float | None = None,
) -> None:
    suffix = f" {unit}" if unit else ""
    given = format_number(value)
    if above is not None and not value > above:
        raise UnitError(f"{given}{suffix} must be greater than {format_number(above)}{suffix}")
    if minimum is not None and value < minimum:
        raise UnitError(f"{given}{suffix} is below the minimum {format_number(minimum)}{suffix}")
    if maximum is not None and value > maximum:
        raise UnitError(f"{given}{suffix} is above the maximum {format_number(maximum)}{suffix}")
