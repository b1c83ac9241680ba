"""Threshold and resolution (IEEE Std 952 / IEEE Std 1431, "threshold" and "resolution").

The plan alternates a base rate and small increments above it (base, base+δ₁, base,
base+δ₂, …, base). Each increment's output change is its dwell mean minus the mean of
the two base dwells either side of it, so a bias drifting linearly over the test cancels.

An increment is *resolved* when that change, referred to the input by the nominal scale
factor, exceeds ``z·u`` (``z`` the one-sided normal quantile of the stated confidence,
``u`` the combined type A uncertainty of the three dwell means) and *within* when it lies
within ``max_error_fraction`` of the commanded increment. The threshold (zero base) or
resolution (non-zero base) is the smallest increment that passes both with every larger
listed increment passing too, so one lucky dwell below a dead zone is not taken for it.

Its uncertainty is that of the grid: the true value lies between the largest failing
increment below it and itself; the estimate reported with it is that interval's middle
with a rectangular standard uncertainty (width/√12) and U = 2u, which covers the whole
interval. The reported ``threshold_dps`` is the increment itself, as the standard defines it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from scipy.stats import norm

COVERAGE_K = 2.0
#: table demands carry 6 decimals (plan.py rounds them); 9 only strips float noise from δ
_INCREMENT_DECIMALS = 9


@dataclass(frozen=True)
class ThresholdDwell:
    """One logged dwell of a threshold test, reduced to its mean."""

    step_id: str
    setpoint_c: float
    base_rate_dps: float
    rate_dps: float
    output_mean: float
    output_sem: float
    confidence: float
    max_error_fraction: float

    @property
    def is_base(self) -> bool:
        return self.rate_dps == self.base_rate_dps


@dataclass(frozen=True)
class Increment:
    commanded_dps: float
    measured_dps: float       # output change ÷ nominal SF
    u_dps: float              # its type A standard uncertainty
    z: float                  # measured / u
    resolved: bool
    within: bool

    @property
    def passes(self) -> bool:
        return self.resolved and self.within

    def to_json(self) -> dict[str, Any]:
        return {"commanded_dps": self.commanded_dps, "measured_dps": self.measured_dps,
                "u_dps": self.u_dps, "z": self.z, "resolved": self.resolved,
                "within": self.within, "passes": self.passes}


def increments(dwells: list[ThresholdDwell], nominal_sf: float) -> list[Increment]:
    """Each increment of one base, in plan order, against its neighbouring base dwells."""
    out = []
    for index, dwell in enumerate(dwells):
        if dwell.is_base:
            continue
        before = _neighbour_base(dwells, index, -1)
        after = _neighbour_base(dwells, index, +1)
        refs = [d for d in (before, after) if d is not None]
        if not refs:
            continue
        ref_mean = sum(d.output_mean for d in refs) / len(refs)
        ref_var = sum(d.output_sem**2 for d in refs) / len(refs) ** 2
        delta = (dwell.output_mean - ref_mean) / nominal_sf
        u = math.sqrt(dwell.output_sem**2 + ref_var) / abs(nominal_sf)
        commanded = round(dwell.rate_dps - dwell.base_rate_dps, _INCREMENT_DECIMALS)
        z_needed = float(norm.ppf(dwell.confidence))
        z = delta / u if u > 0 else math.inf
        out.append(Increment(commanded, delta, u, z, bool(z >= z_needed),
                             abs(delta / commanded - 1.0) <= dwell.max_error_fraction))
    return out


def _neighbour_base(dwells: list[ThresholdDwell], index: int, step: int) -> ThresholdDwell | None:
    other = index + step
    if 0 <= other < len(dwells) and dwells[other].is_base:
        return dwells[other]
    return None


@dataclass(frozen=True)
class Bracket:
    """The smallest passing increment and the largest failing one below it."""

    threshold_dps: float | None
    below_dps: float          # 0 when the smallest increment already passes

    @property
    def estimate_dps(self) -> float | None:
        return None if self.threshold_dps is None else 0.5 * (self.threshold_dps + self.below_dps)

    @property
    def u_dps(self) -> float | None:
        return None if self.threshold_dps is None else (
            (self.threshold_dps - self.below_dps) / math.sqrt(12.0))


def bracket(found: list[Increment]) -> Bracket:
    """The threshold: the smallest increment from which every larger one passes."""
    ordered = sorted(found, key=lambda i: i.commanded_dps)
    threshold = None
    for position in range(len(ordered) - 1, -1, -1):
        if not ordered[position].passes:
            break
        threshold = position
    if threshold is None:
        return Bracket(None, ordered[-1].commanded_dps if ordered else 0.0)
    below = ordered[threshold - 1].commanded_dps if threshold > 0 else 0.0
    return Bracket(ordered[threshold].commanded_dps, below)


@dataclass(frozen=True)
class ThresholdTest:
    """One (temperature, base rate) of a threshold test: its increments and their bracket."""

    temp_c: float
    base_rate_dps: float
    confidence: float
    max_error_fraction: float
    increments: tuple[Increment, ...]
    bracket: Bracket

    @property
    def is_threshold(self) -> bool:
        """A zero base measures the threshold, a non-zero one the resolution."""
        return self.base_rate_dps == 0

    @property
    def threshold_dps(self) -> float | None:
        return self.bracket.threshold_dps

    @property
    def expanded_dps(self) -> float | None:
        u = self.bracket.u_dps
        return None if u is None else COVERAGE_K * u

    def to_json(self) -> dict[str, Any]:
        b = self.bracket
        return {"temp_c": self.temp_c, "base_rate_dps": self.base_rate_dps,
                "standard_test": "threshold (IEEE Std 952 / 1431)" if self.is_threshold
                else "resolution (IEEE Std 952 / 1431)",
                "confidence": self.confidence, "max_error_fraction": self.max_error_fraction,
                "increments": [i.to_json() for i in self.increments],
                "threshold_dps": b.threshold_dps, "below_dps": b.below_dps,
                "estimate_dps": b.estimate_dps, "u_dps": b.u_dps, "U_dps": self.expanded_dps}


@dataclass(frozen=True)
class ThresholdResults:
    """results.json ``threshold``: every test and the headline figures (worst of each kind)."""

    tests: tuple[ThresholdTest, ...]
    threshold_dps: float | None       # worst over the zero-base tests
    resolution_dps: float | None      # worst over the non-zero bases

    def headline_test(self, *, zero: bool) -> ThresholdTest | None:
        """The test the threshold (``zero``) or resolution figure was taken from."""
        value = self.threshold_dps if zero else self.resolution_dps
        if value is None:
            return None
        return next((t for t in self.tests if t.is_threshold == zero
                     and t.threshold_dps == value), None)

    def to_json(self) -> dict[str, Any]:
        return {"tests": [t.to_json() for t in self.tests], "threshold_dps": self.threshold_dps,
                "resolution_dps": self.resolution_dps, "k": COVERAGE_K}


def threshold_section(dwells: list[ThresholdDwell], nominal_sf: float,
                      notes: list[str]) -> ThresholdResults | None:
    """results.json ``threshold``: one entry per (temperature, base rate), and the headline
    figures: the threshold at zero rate and the resolution at the worst non-zero base."""
    if not dwells:
        return None
    groups: dict[tuple[float, float], list[ThresholdDwell]] = {}
    for dwell in dwells:
        groups.setdefault((dwell.setpoint_c, dwell.base_rate_dps), []).append(dwell)
    tests = []
    for (temp, base), members in groups.items():
        found = increments(members, nominal_sf)
        result = bracket(found)
        if result.threshold_dps is None:
            notes.append(f"threshold at {base:+g} deg/s ({temp:g} °C): no listed increment is "
                         "resolved with every larger one; the threshold lies above the largest")
        tests.append(ThresholdTest(temp, base, members[0].confidence,
                                   members[0].max_error_fraction, tuple(found), result))
    return ThresholdResults(tuple(tests), _worst(tests, zero=True), _worst(tests, zero=False))


def _worst(tests: list[ThresholdTest], *, zero: bool) -> float | None:
    values = [t.threshold_dps for t in tests if t.is_threshold == zero]
    if not values or any(v is None for v in values):
        return None
    return max(values)
