"""The safe envelope: every setpoint, ramp, rate and acceleration against both sets of limits.

A value in a procedure is bounded twice: by the procedure's own ``safety:`` block and by
the station's hard ``limits:`` (what the chamber and table can do). Each bounded quantity is
a :class:`Bound` that reads both limits through typed attribute access, so a renamed field
is a type error here rather than a silently skipped check; the key names in it are only
the text that tells the operator where a limit was set.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from gyrocal.orchestrator.procedure.types import (
    MIN_ACCEL_DPS2,
    MIN_RAMP_C_PER_MIN,
    ChamberSafety,
    Safety,
    TableSafety,
)
from gyrocal.orchestrator.station import Station
from gyrocal.problems import KeyPath
from gyrocal.schema import Context
from gyrocal.units import format_number


@dataclass(frozen=True)
class Limit:
    """One limit a value is checked against, and how a message names it."""

    value: float | None
    what: str         # "table limit"
    where: str        # "procedure safety.table.max_rate_dps"


@dataclass(frozen=True)
class Bound:
    """A quantity limited by the procedure's safety block and the station's limits."""

    group: str                                  # chamber | table (in messages)
    key: str                                    # the field's name in both files
    unit: str
    procedure: Callable[[Safety], float]        # its limit in the procedure
    station: Callable[[Station], float]         # its limit in the station


MIN_TEMP = Bound("chamber", "min_temp_c", "°C", lambda s: s.chamber.min_temp_c,
                 lambda st: st.chamber.limits.min_temp_c)
MAX_TEMP = Bound("chamber", "max_temp_c", "°C", lambda s: s.chamber.max_temp_c,
                 lambda st: st.chamber.limits.max_temp_c)
MAX_RAMP = Bound("chamber", "max_ramp_c_per_min", "°C/min", lambda s: s.chamber.max_ramp_c_per_min,
                 lambda st: st.chamber.limits.max_ramp_c_per_min)
MAX_RATE = Bound("table", "max_rate_dps", "deg/s", lambda s: s.table.max_rate_dps,
                 lambda st: st.table.limits.max_rate_dps)
MAX_ACCEL = Bound("table", "max_accel_dps2", "deg/s²", lambda s: s.table.max_accel_dps2,
                  lambda st: st.table.limits.max_accel_dps2)

RAMP_FLOOR = Limit(MIN_RAMP_C_PER_MIN, "plausible minimum", "a slower ramp is a typo")
ACCEL_FLOOR = Limit(MIN_ACCEL_DPS2, "plausible minimum", "a gentler acceleration is a typo")


class Envelope:
    """Reports values outside the limits, each against the tightest limit it breaks."""

    def __init__(self, ctx: Context, safety: Safety | None = None,
                 station: Station | None = None) -> None:
        self.ctx = ctx
        self.safety = safety
        self.station = station

    def limits(self, bound: Bound) -> list[Limit]:
        """Both limits of ``bound``: the procedure's safety block and the station's."""
        limits: list[Limit] = []
        if self.safety is not None:
            limits.append(Limit(bound.procedure(self.safety), f"{bound.group} limit",
                                f"procedure safety.{bound.group}.{bound.key}"))
        if self.station is not None:
            limits.append(Limit(bound.station(self.station), f"{bound.group} limit",
                                f"station {self.station.file}: {bound.group}.limits.{bound.key}"))
        return limits

    def check(self, path: KeyPath, value: float | None, unit: str, *,
              lows: Iterable[Limit] = (), highs: Iterable[Limit] = ()) -> None:
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

    def check_setpoint(self, path: KeyPath, value: float | None) -> None:
        self.check(path, value, MIN_TEMP.unit, lows=self.limits(MIN_TEMP),
                   highs=self.limits(MAX_TEMP))

    def check_ramp(self, path: KeyPath, value: float | None) -> None:
        self.check(path, value, MAX_RAMP.unit, lows=[RAMP_FLOOR], highs=self.limits(MAX_RAMP))

    def check_rate(self, path: KeyPath, value: float | None) -> None:
        self.check(path, value, MAX_RATE.unit, highs=self.limits(MAX_RATE))

    def check_accel(self, path: KeyPath, value: float | None) -> None:
        self.check(path, value, MAX_ACCEL.unit, lows=[ACCEL_FLOOR], highs=self.limits(MAX_ACCEL))

    def check_peak_accel(self, path: KeyPath, frequencies_hz: tuple[float, ...],
                         amplitude_dps: float) -> None:
        """A sinusoid's peak acceleration 2πf·A within the table limits (the first too high)."""
        limits = [lim for lim in self.limits(MAX_ACCEL) if lim.value is not None]
        for index, freq in enumerate(frequencies_hz):
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

    def check_within_station(self, chamber_path: KeyPath, chamber: ChamberSafety,
                             table_path: KeyPath, table: TableSafety) -> None:
        """The procedure's own limits must sit inside what the station can do."""
        station = self.station
        if station is None:
            return

        def station_limit(bound: Bound) -> list[Limit]:
            return [Limit(bound.station(station), f"station {bound.group} limit",
                          f"{station.file}: {bound.group}.limits.{bound.key}")]

        values = ((chamber_path, MIN_TEMP, chamber.min_temp_c, True),
                  (chamber_path, MAX_TEMP, chamber.max_temp_c, False),
                  (chamber_path, MAX_RAMP, chamber.max_ramp_c_per_min, False),
                  (table_path, MAX_RATE, table.max_rate_dps, False),
                  (table_path, MAX_ACCEL, table.max_accel_dps2, False))
        for path, bound, value, is_floor in values:
            side = {"lows" if is_floor else "highs": station_limit(bound)}
            self.check((*path, bound.key), value, bound.unit, **side)
