"""The acceptance limits: a metric of the catalogue, one bound, its unit and decision rule.

A limit is refused here when its metric is unknown, its unit is not the metric's, it
could never be met, or the sequence measures nothing the metric is computed from, so a
limit that cannot be judged is found before the night, not in the morning's report.
"""

from __future__ import annotations

import difflib

from gyrocal.metrology.metrics import METRICS, Need, units_match
from gyrocal.orchestrator.procedure.reading import Reading
from gyrocal.orchestrator.procedure.types import (
    AcceptanceLimit,
    AllanTest,
    FrequencyResponseTest,
    RateLimitTest,
    SweepTest,
    TemperatureStep,
    ThresholdTest,
    TurnOnRepeatabilityTest,
    TurnOnTest,
)
from gyrocal.problems import KeyPath
from gyrocal.schema import Fields, number, text
from gyrocal.units import UnitError, describe, format_number


def read_acceptance(reading: Reading, parent: Fields,
                    sequence: tuple[TemperatureStep, ...]) -> tuple[AcceptanceLimit, ...]:
    """The ``acceptance:`` list; names are unique and every metric can be computed."""
    present, raw = parent.raw("acceptance")
    if not present:
        return ()
    measured = what_is_measured(sequence)
    limits: list[AcceptanceLimit] = []
    names: dict[str, int] = {}
    for index, item in enumerate(reading.items(("acceptance",), raw, "acceptance",
                                               allow_empty=True)):
        fields = Fields(reading.ctx, ("acceptance", index), item, "an acceptance limit")
        if not fields.valid:
            continue
        limit = _limit(reading, fields, names, measured, bool(sequence))
        if limit is not None:
            limits.append(limit)
    return tuple(limits)


def _limit(reading: Reading, fields: Fields, names: dict[str, int], measured: set[Need],
           has_sequence: bool) -> AcceptanceLimit | None:
    """One limit; None when its metric is not known (already reported).

    ``names`` maps each name read so far to its index, to refuse a name used twice.
    """
    path: KeyPath = fields.path
    name = fields.take("name", text)
    metric = fields.take("metric", _metric)
    maximum = fields.take("max", number(), required=False)
    minimum = fields.take("min", number(), required=False)
    unit = fields.take("unit", text, required=False)
    rule = fields.take("decision_rule", _decision_rule, required=False)
    fields.finish()
    if fields.has("max") == fields.has("min"):
        reading.report(path, "give exactly one of max or min")
    if maximum is not None and maximum < 0 and metric is not None:
        # every max limit bounds a size, a spread or (signed metrics) a magnitude
        reading.report(fields.child("max"), f"max {format_number(maximum)} can never be "
                       f"met: {metric} is judged by its size, which is never negative")
    if name is not None:
        if name in names:
            reading.report(fields.child("name"),
                           f"name {name!r} is used twice (also acceptance[{names[name]}])")
        names.setdefault(name, int(path[-1]))
    if metric is None:
        return None
    spec = METRICS[metric]
    if unit is not None and not units_match(unit, spec):
        reading.report(fields.child("unit"), f"{metric} is in {spec.unit}, not {unit}")
    if unit is None:
        # a limit given without its unit is in the metric's (the report prints it)
        unit = spec.unit if spec.unit is not None else reading.output_units
    if spec.needs not in measured and has_sequence:
        reading.report(fields.child("metric"), f"{metric} cannot be computed: it needs "
                       f"{spec.needs.text} in the sequence")
    return AcceptanceLimit(name, metric, maximum, minimum, unit, rule or "simple")


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


def what_is_measured(sequence: tuple[TemperatureStep, ...]) -> set[Need]:
    """What the sequence measures, in the terms of the metrics' ``needs``."""
    sweep_temps: set[float] = set()
    bias_temps: set[float] = set()
    measured: set[Need] = set()
    plain = {SweepTest: Need.SWEEP, ThresholdTest: Need.THRESHOLD,
             FrequencyResponseTest: Need.FREQUENCY_RESPONSE, TurnOnTest: Need.TURN_ON,
             TurnOnRepeatabilityTest: Need.TURN_ON_REPEATABILITY}
    for step in sequence:
        for test in step.tests:
            if type(test) in plain:
                measured.add(plain[type(test)])
                if isinstance(test, SweepTest):
                    sweep_temps.add(step.setpoint_c)
            elif isinstance(test, RateLimitTest):
                signs = (1.0, -1.0) if test.directions == "both" else (
                    1.0 if test.directions == "positive" else -1.0,)
                measured.update(Need.rate_limit(sign) for sign in signs)
            else:
                bias_temps.add(step.setpoint_c)
                if isinstance(test, AllanTest):
                    measured.add(Need.ALLAN)
    if len(sweep_temps) >= 2:
        measured.add(Need.SWEEP_TEMPS)
    if len(bias_temps) >= 2:
        measured.add(Need.BIAS_TEMPS)
    return measured
