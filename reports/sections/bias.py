"""The bias figures of results.json, typed: ``bias`` per temperature and ``bias_temperature``.

As with the sweep, a value's uncertainty is computed apart
(:mod:`gyrocal.reports.sections.uncertainty`) and put beside it by ``to_json``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Any

from gyrocal.metrology.gum import Uncertainty


class BiasSource(str, Enum):
    """Where a temperature's bias comes from."""

    STATIC = "static"                    # the static/allan holds there
    SWEEP_INTERCEPT = "sweep_intercept"  # the LS line's intercept (no hold at that setpoint)


@dataclass(frozen=True)
class BiasEntry:
    """The bias at one setpoint, Earth rate removed (deg/h)."""

    temp_c: float
    bias_dph: float
    source: BiasSource
    sensor_temp_c: float | None

    def to_json(self, u: Uncertainty | None = None) -> dict[str, Any]:
        out = {"temp_c": self.temp_c, "bias_dph": self.bias_dph, "source": self.source.value,
               "sensor_temp_c": self.sensor_temp_c}
        return out if u is None else out | u.to_json()


@dataclass(frozen=True)
class BiasResults:
    """``bias`` (per setpoint, ascending) and ``bias_temperature`` (None below two setpoints)."""

    entries: tuple[BiasEntry, ...]
    sensitivity_dph_per_c: float | None

    def to_json(self, per_temp: Mapping[float, Uncertainty] | None = None,
                slope: Uncertainty | None = None) -> dict[str, Any]:
        per_temp = per_temp or {}
        sensitivity = None
        if self.sensitivity_dph_per_c is not None:
            sensitivity = {"sensitivity_dph_per_c": self.sensitivity_dph_per_c}
            if slope is not None:
                sensitivity |= slope.to_json()
        return {"bias": [e.to_json(per_temp.get(e.temp_c)) for e in self.entries],
                "bias_temperature": sensitivity}
