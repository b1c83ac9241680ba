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
class Way:
    """One direction's walk: the maximum rate that follows and the first that does not."""

    sign: float
    max_dps: float | None         # magnitude; None when not even the smallest rate follows
    next_dps: float | None        # the first rate that does not follow; None if all do
    points: list[dict[str, Any]]

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
        points.append({"rate_dps": dwell.rate_dps, "output_mean": dwell.output_mean,
                       "fitted": fitted, "deviation_pct": deviation_pct, "follows": follows})
        if next_dps is None:
            if follows:
                max_dps = abs(dwell.rate_dps)
            else:
                next_dps = abs(dwell.rate_dps)
    return Way(sign, max_dps, next_dps, points)


def rate_limits_section(dwells: list[LimitDwell], notes: list[str]) -> dict[str, Any] | None:
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
            way = walk(members, sign, sf, bias)
            name = "positive" if sign > 0 else "negative"
            if way.next_dps is None:
                notes.append(f"rate limits at {temp:g} °C, {name}: every rate walked follows the "
                             f"linear fit; the limit is above {way.max_dps:g} deg/s (a lower bound)")
            u = way.u_dps
            tests.append({"temp_c": temp, "direction": name, "standard_test":
                          "input rate limits (IEEE Std 952 / 1431)", "fit_sf": sf, "fit_bias": bias,
                          "linearity_tolerance_pct": members[0].linearity_tolerance_pct,
                          "points": way.points, "max_dps": way.max_dps, "next_dps": way.next_dps,
                          "estimate_dps": way.estimate_dps, "u_dps": u,
                          "U_dps": None if u is None else COVERAGE_K * u})
    return {"tests": tests, "max_positive_dps": _smallest(tests, "positive"),
            "max_negative_dps": _smallest(tests, "negative"), "k": COVERAGE_K}


def _smallest(tests: list[dict[str, Any]], direction: str) -> float | None:
    values = [t["max_dps"] for t in tests if t["direction"] == direction]
    if not values or any(v is None for v in values):
        return None
    return min(values)


def headline_uncertainty(section: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    if section is None:
        return out
    for direction in ("positive", "negative"):
        value = section[f"max_{direction}_dps"]
        entry = next((t for t in section["tests"] if t["direction"] == direction
                      and t["max_dps"] == value), None)
        if value is None or entry is None or entry["u_dps"] is None:
            continue
        out[f"rate_limits.max_{direction}_dps"] = {
            "value": value, "u": entry["u_dps"], "U": entry["U_dps"], "k": COVERAGE_K,
            "unit": "deg/s", "method": "rectangular over the rate walk (largest rate that "
                                       "follows to the first that does not)"}
    return out
