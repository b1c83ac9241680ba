"""The table rates a test turns at: listed or generated, each one a table can be commanded.

Every rate is held at the table's command resolution (``commanded_rate_dps``: what a rate
demand carries), listed once, and inside the envelope, so the plan never asks the table
for a rate it would round, repeat, or refuse.
"""

from __future__ import annotations

import math

from gyrocal.instruments.table.acutrol_protocol import RATE_DECIMALS, commanded_rate_dps
from gyrocal.orchestrator.procedure.reading import Reading
from gyrocal.orchestrator.procedure.types import MAX_LIST, SPACINGS, RateSchedule
from gyrocal.problems import KeyPath
from gyrocal.schema import Fields, choice, integer, quantity
from gyrocal.units import RATE, UnitError, format_number


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


def _too_fine(rate: float) -> str | None:
    if rate == commanded_rate_dps(rate):
        return None
    return (f"{rate!r} deg/s is finer than a table demand carries ({RATE_DECIMALS} decimals); "
            f"give {commanded_rate_dps(rate)!r}")


def sweep_rates(reading: Reading, fields: Fields) -> tuple[tuple[float, ...], RateSchedule | None]:
    """A sweep's rates: ``rates_dps`` (a list) or ``schedule`` (generated), exactly one."""
    has_list, has_schedule = fields.has("rates_dps"), fields.has("schedule")
    fields.used.update({"rates_dps", "schedule"})
    if has_list == has_schedule:
        if fields.valid:
            reading.report(fields.path, "give either rates_dps (a list) or schedule "
                           "(spacing, start_dps, stop_dps, count), not both"
                           if has_list else "missing rates: give rates_dps (a list) or "
                           "schedule (spacing, start_dps, stop_dps, count)")
        return (), None
    if has_list:
        return rate_list(reading, fields.child("rates_dps"), fields.data["rates_dps"]), None
    return rate_schedule(reading, reading.section(fields, "schedule"))


def rate_list(reading: Reading, path: KeyPath, raw: object) -> tuple[float, ...]:
    """Magnitudes (> 0), each once, at the command resolution, within the envelope."""
    convert = quantity(RATE, above=0.0)
    rates: list[float] = []
    first_index: dict[float, int] = {}
    for index, item in enumerate(reading.items(path, raw, "rates_dps")):
        item_path = (*path, index)
        try:
            rate = convert(item)
        except UnitError as error:
            message = str(error)
            if "must be greater than 0" in message:
                message += " (give magnitudes; `directions` sets the signs)"
            reading.report(item_path, message)
            continue
        problem = _too_fine(rate)
        if problem is None and rate in first_index:
            problem = (f"{format_number(rate)} deg/s is listed twice "
                       f"(also rates_dps[{first_index[rate]}])")
        if problem is not None:
            reading.report(item_path, problem)
            continue
        first_index[rate] = index
        reading.envelope.check_rate(item_path, rate)
        rates.append(rate)
    return tuple(rates)


def increasing_rates(reading: Reading, fields: Fields, key: str, what: str,
                     advice: str) -> tuple[float, ...]:
    """:func:`rate_list` at ``key``, strictly increasing; () after the first that is not."""
    present, raw = reading.required_raw(fields, key)
    if not present:
        return ()
    rates = rate_list(reading, fields.child(key), raw)
    for index, (before, after) in enumerate(zip(rates, rates[1:], strict=False)):
        if after <= before:
            reading.report((*fields.child(key), index + 1),
                           f"{format_number(after)} deg/s is not larger than the {what} "
                           f"before it ({format_number(before)} deg/s); {advice}")
            return ()
    return rates


def rate_schedule(reading: Reading, fields: Fields) -> tuple[tuple[float, ...], RateSchedule | None]:
    """``count`` rates from ``start_dps`` to ``stop_dps``, linear or log, all distinct."""
    spacing = fields.take("spacing", choice(SPACINGS))
    start = fields.take("start_dps", quantity(RATE, above=0.0))
    stop = fields.take("stop_dps", quantity(RATE, above=0.0))
    count = fields.take("count", integer(1, MAX_LIST))
    fields.finish()
    if None in (spacing, start, stop, count):
        return (), None
    if stop < start:
        reading.report(fields.child("stop_dps"), f"{format_number(stop)} deg/s is below "
                       f"start_dps {format_number(start)} deg/s")
        return (), None
    if count == 1 and stop != start:
        reading.report(fields.child("count"), "count 1 needs start_dps == stop_dps")
        return (), None
    reading.envelope.check_rate(fields.child("stop_dps"), stop)
    rates = generate_rates(spacing, start, stop, count)
    if len(set(rates)) != len(rates):
        reading.report(fields.child("count"), f"{count} rates between {format_number(start)} "
                       f"and {format_number(stop)} deg/s repeat at the table's command resolution; "
                       "use fewer")
        return (), None
    return rates, RateSchedule(spacing, start, stop, count)


def signed_rate_list(reading: Reading, fields: Fields, key: str) -> tuple[float, ...]:
    """Base rates: signed, 0 allowed, at the table's command resolution, each once."""
    present, raw = reading.required_raw(fields, key)
    if not present:
        return ()
    convert = quantity(RATE)
    rates: list[float] = []
    for index, item in enumerate(reading.items(fields.child(key), raw, key)):
        item_path = (*fields.child(key), index)
        try:
            rate = convert(item)
        except UnitError as error:
            reading.report(item_path, str(error))
            continue
        problem = _too_fine(rate)
        if problem is None and rate in rates:
            problem = (f"{format_number(rate)} deg/s is listed twice "
                       f"(also {key}[{rates.index(rate)}])")
        if problem is not None:
            reading.report(item_path, problem)
            continue
        reading.envelope.check_rate(item_path, abs(rate))
        rates.append(rate)
    return tuple(rates)


def increment_list(reading: Reading, fields: Fields, bases: tuple[float, ...]) -> tuple[float, ...]:
    """Increments: positive, strictly increasing, and base + increment within the limits."""
    increments = increasing_rates(reading, fields, "increments_dps", "increment",
                                  "list them smallest first")
    if increments:
        for index, base in enumerate(bases):
            top = abs(base) + increments[-1]
            reading.envelope.check_rate((*fields.child("base_rates_dps"), index), top)
    return increments
