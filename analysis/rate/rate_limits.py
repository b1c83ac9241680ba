"""Input-rate limits (IEEE Std 952 / IEEE Std 1431, "input rate limits").

The plan walks rates up to the declared maximum each way. The lowest ``fit_rates``
rates of every direction walked at a temperature define a least-squares line
(output = SF·ω + b); a rate *follows* when its dwell mean lies within
``linearity_tolerance_pct`` of that line's output at it. The maximum input rate each way
is the largest rate that follows with every smaller one; the next rate walked (the
first that does not) bounds it from above.

Its uncertainty is the walk's grid: the unit's true limit lies between the maximum and
the next rate, so a rectangular u = width/√12 about their middle, U = 2u, covers that
interval. When every rate follows, the limit was not reached: the maximum is the
largest rate walked, a lower bound, with no U (a note says so).

Saturation status bits: the simulated STIM300 sets its overload bits only at its
datagram full scale (±512 deg/s, beyond every table limit here), and flagged samples
are dropped as bad data before this analysis; the walk reads the output alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

COVERAGE_K = 2.0


@dataclass(frozen=True)
class LimitDwell:
    step_id: str
    setpoint_c: float
    rate_dps: float
    output_mean: float
    linearity_tolerance_pct: float
    fit_rates: int


@dataclass(frozen=True)
class WalkPoint:
    """One walked rate against the line: does it follow within the tolerance?"""

    rate_dps: float
    output_mean: float
    fitted: float
    deviation_pct: float
    follows: bool

    def to_json(self) -> dict[str, Any]:
        return {"rate_dps": self.rate_dps, "output_mean": self.output_mean,
                "fitted": self.fitted, "deviation_pct": self.deviation_pct,
                "follows": self.follows}


@dataclass(frozen=True)
class Way:
    """One direction's walk: the maximum rate that follows and the first that does not."""

    sign: float
    max_dps: float | None         # magnitude; None when not even the smallest rate follows
    next_dps: float | None        # the first rate that does not follow; None if all do
    points: tuple[WalkPoint, ...]

    @property
    def u_dps(self) -> float | None:
        if self.max_dps is None or self.next_dps is None:
            return None
        return (self.next_dps - self.max_dps) / math.sqrt(12.0)

    @property
    def estimate_dps(self) -> float | None:
        if self.max_dps is None or self.next_dps is None:
            return None
        return 0.5 * (self.max_dps + self.next_dps)


def linear_fit(dwells: list[LimitDwell]) -> tuple[float, float]:
    """(SF, bias) of the LS line through the lowest ``fit_rates`` rates of each direction."""
    count = dwells[0].fit_rates
    chosen: list[LimitDwell] = []
    for sign in (1.0, -1.0):
        way = sorted((d for d in dwells if math.copysign(1.0, d.rate_dps) == sign),
                     key=lambda d: abs(d.rate_dps))
        chosen += way[:count]
    rates = np.array([d.rate_dps for d in chosen])
    means = np.array([d.output_mean for d in chosen])
    if np.unique(rates).size < 2:
        raise ValueError("the linear fit needs two different rates")
    sf, bias = np.polyfit(rates, means, 1)
    return float(sf), float(bias)


def walk(dwells: list[LimitDwell], sign: float, sf: float, bias: float) -> Way:
    way = sorted((d for d in dwells if math.copysign(1.0, d.rate_dps) == sign),
                 key=lambda d: abs(d.rate_dps))
    points = []
    max_dps = next_dps = None
    for dwell in way:
        fitted = sf * dwell.rate_dps + bias
        deviation_pct = abs(dwell.output_mean - fitted) / abs(sf * dwell.rate_dps) * 100.0
        follows = deviation_pct <= dwell.linearity_tolerance_pct
        points.append(WalkPoint(dwell.rate_dps, dwell.output_mean, fitted, deviation_pct, follows))
        if next_dps is None:
            if follows:
                max_dps = abs(dwell.rate_dps)
            else:
                next_dps = abs(dwell.rate_dps)
    return Way(sign, max_dps, next_dps, tuple(points))


@dataclass(frozen=True)
class LimitTest:
    """One direction walked at one temperature, against that temperature's line."""

    temp_c: float
    fit_sf: float
    fit_bias: float
    linearity_tolerance_pct: float
    way: Way

    @property
    def direction(self) -> str:
        return "positive" if self.way.sign > 0 else "negative"

    @property
    def expanded_dps(self) -> float | None:
        u = self.way.u_dps
        return None if u is None else COVERAGE_K * u

    def to_json(self) -> dict[str, Any]:
        way = self.way
        return {"temp_c": self.temp_c, "direction": self.direction,
                "standard_test": "input rate limits (IEEE Std 952 / 1431)",
                "fit_sf": self.fit_sf, "fit_bias": self.fit_bias,
                "linearity_tolerance_pct": self.linearity_tolerance_pct,
                "points": [p.to_json() for p in way.points], "max_dps": way.max_dps,
                "next_dps": way.next_dps, "estimate_dps": way.estimate_dps, "u_dps": way.u_dps,
                "U_dps": self.expanded_dps}


@dataclass(frozen=True)
class RateLimitResults:
    """results.json ``rate_limits``: every walk, and the smallest maximum each way."""

    tests: tuple[LimitTest, ...]
    max_positive_dps: float | None
    max_negative_dps: float | None

    def headline_test(self, sign: float) -> LimitTest | None:
        """The walk the maximum of one direction was taken from."""
        value = self.max_positive_dps if sign > 0 else self.max_negative_dps
        if value is None:
            return None
        return next((t for t in self.tests if t.way.sign == sign and t.way.max_dps == value),
                    None)

    def to_json(self) -> dict[str, Any]:
        return {"tests": [t.to_json() for t in self.tests],
                "max_positive_dps": self.max_positive_dps,
                "max_negative_dps": self.max_negative_dps, "k": COVERAGE_K}


def rate_limits_section(dwells: list[LimitDwell], notes: list[str]) -> RateLimitResults | None:
    """results.json ``rate_limits``: the walk per temperature and direction, and the smallest
    maximum each way over temperatures."""
    if not dwells:
        return None
    groups: dict[float, list[LimitDwell]] = {}
    for dwell in dwells:
        groups.setdefault(dwell.setpoint_c, []).append(dwell)
    tests = []
    for temp, members in groups.items():
        try:
            sf, bias = linear_fit(members)
        except ValueError as exc:
            notes.append(f"rate limits at {temp:g} °C not computed: {exc}")
            continue
        for sign in sorted({math.copysign(1.0, d.rate_dps) for d in members}, reverse=True):
            test = LimitTest(temp, sf, bias, members[0].linearity_tolerance_pct,
                             walk(members, sign, sf, bias))
            if test.way.next_dps is None:
                notes.append(f"rate limits at {temp:g} °C, {test.direction}: every rate walked "
                             "follows the linear fit; the limit is above "
                             f"{test.way.max_dps:g} deg/s (a lower bound)")
            tests.append(test)
    return RateLimitResults(tuple(tests), _smallest(tests, 1.0), _smallest(tests, -1.0))


def _smallest(tests: list[LimitTest], sign: float) -> float | None:
    values = [t.way.max_dps for t in tests if t.way.sign == sign]
    if not values or any(v is None for v in values):
        return None
    return min(values)
