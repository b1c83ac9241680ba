"""The ± rate sweep's figures of results.json, typed: per-temperature scale factor, the single numbers.

``scale_factor`` (one entry per setpoint), ``scale_factor_ls``, ``nonlinearity``,
``asymmetry_ppm`` and ``sf_temperature`` (interfaces.md). The uncertainty of each is
not part of the measured value: :mod:`gyrocal.reports.sections.uncertainty` computes
it from the same dwells and ``to_json`` puts it beside the value.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gyrocal.analysis.rate.scale_factor import ScaleFactorResult
from gyrocal.analysis.thermal.bias import SfTemperature
from gyrocal.metrology.gum import Uncertainty


@dataclass(frozen=True)
class ScaleFactorEntry:
    """One setpoint's LS line, per-rate SF, residuals, nonlinearity and asymmetry."""

    result: ScaleFactorResult
    sensor_temp_c: float | None
    chamber_temp_c: float | None
    #: (rate deg/s, residual in ppm of full scale), sorted by rate
    residuals_ppm_fs: tuple[tuple[float, float], ...]

    @property
    def temp_c(self) -> float:
        return self.result.temp_c

    def to_json(self, u: Mapping[str, Uncertainty] | None = None) -> dict[str, Any]:
        """The ``scale_factor`` entry; ``u`` (figure → budget at this temperature) adds the
        SF's u/U/k/budget beside it and the other figures' under ``uncertainty``."""
        r = self.result
        out = r.to_json() | {
            "bias": r.bias,
            "sensor_temp_c": self.sensor_temp_c,
            "chamber_temp_c": self.chamber_temp_c,
            "sf_by_rate": [[rate, sf] for rate, sf in sorted(r.sf_by_rate.items())],
            "residuals_ppm_fs": [[rate, res] for rate, res in self.residuals_ppm_fs],
            "nonlinearity": {"rms_pct": r.nonlinearity_rms_pct,
                             "max_ppm_fs": r.nonlinearity_max_ppm_fs},
            "asymmetry_ppm": r.asymmetry_ppm,
        }
        if u is not None:
            out |= u["sf"].to_json()
            out["uncertainty"] = {k: v.to_json() for k, v in u.items() if k != "sf"}
        return out


@dataclass(frozen=True)
class SweepResults:
    """The sweep's sections; ``entries`` empty when no ± sweep completed."""

    entries: tuple[ScaleFactorEntry, ...]
    reference_temp_c: float          # the single numbers' reference (closest setpoint wins)
    sf_temperature: SfTemperature | None

    @property
    def reference(self) -> ScaleFactorEntry | None:
        """The LS line at the setpoint closest to the reference temperature (a tie: the lower)."""
        return min(self.entries, key=lambda e: abs(e.temp_c - self.reference_temp_c),
                   default=None)

    @property
    def worst_rms(self) -> ScaleFactorEntry | None:
        return max(self.entries, key=lambda e: e.result.nonlinearity_rms_pct, default=None)

    @property
    def worst_max(self) -> ScaleFactorEntry | None:
        return max(self.entries, key=lambda e: e.result.nonlinearity_max_ppm_fs, default=None)

    @property
    def largest_asymmetry(self) -> ScaleFactorEntry | None:
        """The entry of largest |asymmetry| (the first of equals), its sign kept."""
        return max(self.entries, key=lambda e: abs(e.result.asymmetry_ppm), default=None)

    def to_json(self, per_temp: Mapping[float, Mapping[str, Uncertainty]] | None = None
                ) -> dict[str, Any]:
        """scale_factor … sf_temperature; ``per_temp``: each setpoint's budgets, when computed."""
        per_temp = per_temp or {}
        ref, rms, worst, asym = self.reference, self.worst_rms, self.worst_max, \
            self.largest_asymmetry
        ls = None
        if ref is not None:
            ls = {"sf": ref.result.sf, "bias": ref.result.bias, "temp_c": ref.temp_c}
            if ref.temp_c in per_temp:
                ls |= per_temp[ref.temp_c]["sf"].to_json()
        return {
            "scale_factor": [e.to_json(per_temp.get(e.temp_c)) for e in self.entries],
            "scale_factor_ls": ls,
            "nonlinearity": None if rms is None or worst is None else {
                "rms_pct": rms.result.nonlinearity_rms_pct,
                "max_ppm_fs": worst.result.nonlinearity_max_ppm_fs},
            "asymmetry_ppm": None if asym is None else asym.result.asymmetry_ppm,
            "sf_temperature": None if self.sf_temperature is None
            else self.sf_temperature.to_json(),
        }
