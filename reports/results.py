"""The report's results, typed, and their one encoding: ``report/results.json``.

Each section is built by its own module as a typed value (sweep, bias, Allan,
compensation, run, the uncertainty budget, the acceptance verdicts);
:meth:`Results.to_json` is the only place that lays them out as the file's keys
(interfaces.md: those keys stay, new ones may be added), each budget beside the
value it belongs to; the tests beyond the sweep, bias and Allan are
:class:`TestSections`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gyrocal.analysis.rate.rate_limits import RateLimitResults
from gyrocal.analysis.rate.threshold import ThresholdResults
from gyrocal.metrology.decision import OverallVerdict
from gyrocal.reports.acceptance import AcceptanceVerdict
from gyrocal.reports.run_info import Provenance
from gyrocal.reports.sections.allan import AllanSection
from gyrocal.reports.sections.bias import BiasResults
from gyrocal.reports.sections.compensation import CompensationResults
from gyrocal.reports.sections.frequency import FrequencyResults, frequency_uncertainty
from gyrocal.reports.sections.headline import StatedUncertainty, keyed
from gyrocal.reports.sections.imu import ImuResults
from gyrocal.reports.sections.interference import InterferenceEntry
from gyrocal.reports.sections.magnetic import MagneticEntry
from gyrocal.reports.sections.rate_limits import rate_limits_uncertainty
from gyrocal.reports.sections.sweep import SweepResults
from gyrocal.reports.sections.threshold import threshold_uncertainty
from gyrocal.reports.sections.tilt import TiltEntry
from gyrocal.reports.sections.turn_on import (
    RepeatabilityResults,
    TurnOnResults,
    repeatability_uncertainty,
    turn_on_uncertainty,
)
from gyrocal.reports.sections.uncertainty import UncertaintyBudget

#: The keys interfaces.md requires in report/results.json.
REQUIRED_KEYS = ("unit_under_test", "scale_factor", "scale_factor_ls", "nonlinearity",
                 "asymmetry_ppm", "sf_temperature", "bias", "bias_temperature", "allan",
                 "compensation", "acceptance")
#: results.json keys that are numbers computed from the samples (``gyrocal verify`` recomputes).
RECOMPUTED_KEYS = ("unit_under_test", "scale_factor", "scale_factor_ls", "nonlinearity",
                   "asymmetry_ppm", "sf_temperature", "bias", "bias_temperature", "allan",
                   "compensation", "imu", "acceptance", "verdict")


@dataclass(frozen=True)
class UnitUnderTest:
    model: str | None
    serial: str | None
    output_units: str | None
    nominal_scale_factor: float      # output units per deg/s

    def to_json(self) -> dict[str, Any]:
        return {"model": self.model, "serial": self.serial, "output_units": self.output_units,
                "nominal_scale_factor": self.nominal_scale_factor}


@dataclass(frozen=True)
class TestSections:
    """The sections of the tests beyond the sweep, bias and Allan: imu … turn_on_repeatability,
    each None when the run has no such test; ``to_json`` lays them out in file order."""

    imu: ImuResults | None
    table_interference: tuple[InterferenceEntry, ...] | None
    magnetic: tuple[MagneticEntry, ...] | None
    tilt_linearity: tuple[TiltEntry, ...] | None
    threshold: ThresholdResults | None
    rate_limits: RateLimitResults | None
    frequency_response: FrequencyResults | None
    turn_on: TurnOnResults | None
    turn_on_repeatability: RepeatabilityResults | None

    def stated_uncertainties(self) -> dict[str, StatedUncertainty]:
        """results.json ``uncertainty`` entries these sections state for their single figures."""
        return keyed([*threshold_uncertainty(self.threshold),
                      *rate_limits_uncertainty(self.rate_limits),
                      *frequency_uncertainty(self.frequency_response),
                      *turn_on_uncertainty(self.turn_on),
                      *repeatability_uncertainty(self.turn_on_repeatability)])

    def to_json(self) -> dict[str, Any]:
        def entries(found: tuple[Any, ...] | None) -> list[dict[str, Any]] | None:
            return None if found is None else [e.to_json() for e in found]

        def block(found: Any) -> dict[str, Any] | None:
            return None if found is None else found.to_json()
        return {"imu": block(self.imu), "table_interference": entries(self.table_interference),
                "magnetic": entries(self.magnetic), "tilt_linearity": entries(self.tilt_linearity),
                "threshold": block(self.threshold), "rate_limits": block(self.rate_limits),
                "frequency_response": block(self.frequency_response),
                "turn_on": block(self.turn_on),
                "turn_on_repeatability": block(self.turn_on_repeatability)}


@dataclass(frozen=True)
class Results:
    """Everything results.json states; the verdict fields are None until judged."""

    unit_under_test: UnitUnderTest
    sweep: SweepResults
    bias: BiasResults
    allan: AllanSection | None
    compensation: CompensationResults
    sections: TestSections
    earth_rate_removed_dph: float
    reference_temp_c: float
    provenance: Provenance
    definitions: Mapping[str, str]
    budget: UncertaintyBudget
    #: the uncertainties the test sections state for their single figures (metric key → it)
    headline_uncertainty: Mapping[str, StatedUncertainty]
    acceptance: tuple[AcceptanceVerdict, ...] | None = None
    verdict: OverallVerdict | None = None
    notes: tuple[str, ...] | None = None
    built_at: str | None = None
    signature: Mapping[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """results.json's object, keys in file order (NaN/inf still in; see results_bytes)."""
        b = self.budget
        out: dict[str, Any] = {
            "unit_under_test": self.unit_under_test.to_json(),
            **self.sweep.to_json(b.sweep),
            **self.bias.to_json(b.bias, b.bias_slope),
            "allan": None if self.allan is None else self.allan.to_json(b.allan),
            "compensation": self.compensation.to_json(b.compensation),
            **self.sections.to_json(),
            "earth_rate_removed_dph": self.earth_rate_removed_dph,
            "reference_temp_c": self.reference_temp_c,
            **self.provenance.to_json(),
            "definitions": dict(self.definitions),
            "uncertainty": b.paths_json() | {key: stated.to_json() for key, stated
                                             in self.headline_uncertainty.items()},
            "uncertainty_inputs": b.inputs.to_json(),
        }
        if self.acceptance is not None:
            out["acceptance"] = [v.to_json() for v in self.acceptance]
        if self.verdict is not None:
            out["verdict"] = self.verdict.to_json()
        if self.notes is not None:
            out["notes"] = list(self.notes)
        if self.built_at is not None:
            out["report_built_at"] = self.built_at
        if self.signature is not None:
            out["signature"] = dict(self.signature)
        return out


def finite_or_none(value: Any) -> Any:
    """JSON has no NaN/inf: such a number becomes null (recursively)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return finite_or_none(value.item())
    return value


def results_bytes(results: dict[str, Any]) -> bytes:
    """Canonical, NaN-free encoding of results.json."""
    return json.dumps(finite_or_none(results), indent=2, allow_nan=False).encode() + b"\n"
