"""What every part of the procedure parser shares while one file is read.

The parser is split by job (``parser.py``: the top level, conditions and defaults;
``kinds.py``: one reader per test kind; ``rates.py``: rate lists and schedules;
``acceptance.py``: the limits). They all report into one :class:`Context`, check values
against one :class:`Envelope` and inherit from the same ``defaults:``, held here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gyrocal.orchestrator.procedure.envelope import Envelope
from gyrocal.orchestrator.procedure.types import MAX_DURATION_S, MAX_LIST
from gyrocal.orchestrator.station import Station
from gyrocal.problems import KeyPath
from gyrocal.schema import Context, Fields, duration
from gyrocal.units import UnitError, describe


@dataclass
class Reading:
    """The state of reading one procedure: problems, station, envelope, broken defaults."""

    ctx: Context
    station: Station | None = None
    envelope: Envelope = field(init=False)
    output_units: str | None = None   # the unit under test's, once read
    #: defaults that were given but invalid: already reported, so a test that inherits
    #: them is not also told the key is missing
    broken_defaults: set[str] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.envelope = Envelope(self.ctx)

    def report(self, path: KeyPath, message: str) -> None:
        self.ctx.report(path, message)

    def section(self, parent: Fields, key: str, *, required: bool = True) -> Fields:
        """The mapping at ``key``; an empty one (reported if required) when it is missing."""
        present, raw = parent.raw(key)
        if not present:
            if required and parent.valid:
                self.ctx.report(parent.child(key), "required key is missing")
            return Fields(self.ctx, parent.child(key), {}, key)
        return Fields(self.ctx, parent.child(key), raw, key)

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

    def required_raw(self, fields: Fields, key: str) -> tuple[bool, Any]:
        """Presence and raw value of a key the caller parses; missing is reported."""
        present, raw = fields.raw(key)
        if not present and fields.valid:
            self.ctx.report(fields.child(key), "required key is missing")
        return present, raw

    def items(self, path: KeyPath, value: object, what: str, *,
              allow_empty: bool = False) -> list:
        """The entries of a list, at most :data:`MAX_LIST`; anything else is reported."""
        if not isinstance(value, list):
            self.ctx.report(path, f"{what} must be a list, got {describe(value)}")
            return []
        if not value and not allow_empty:
            self.ctx.report(path, f"{what} must not be empty")
        if len(value) > MAX_LIST:
            self.ctx.report(path, f"{what} has {len(value)} entries; at most {MAX_LIST} are allowed")
            return []
        return value


def bounded_duration(positive: bool = True) -> Callable[[object], float]:
    """A duration of at most :data:`MAX_DURATION_S`: a longer step is a typo."""
    base = duration(positive=positive)

    def convert(value: object) -> float:
        seconds = base(value)
        if seconds > MAX_DURATION_S:
            raise UnitError(f"{value!r} is longer than 7 days; a typo?")
        return seconds
    return convert
