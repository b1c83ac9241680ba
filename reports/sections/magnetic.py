"""The ``magnetic`` block of results.json: each magnetic test's bias regressed on the coil's field.

A ``magnetic`` test plans three statics, ``….mag.pos``, ``….mag.zero`` and
``….mag.neg`` (+B, 0, -B along the station's coil axis). Each step's bias is
its mean output ÷ the nominal scale factor (deg/h) with the batch-means
standard uncertainty; its field is the one the coil read back when set (the
``coil_field`` journal event), else the planned one. The sensitivity and its
GUM uncertainty (type A from the dwells, type B from the coil constant) come
from ``magnetic.py``; k from the effective degrees of freedom.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from gyrocal.analysis.environment.magnetic import MagneticSensitivity, sensitivity
from gyrocal.metrology.gum import Contribution, EvalType, Uncertainty, combine
from gyrocal.record.journal import JournalEvent
from gyrocal.record.step_kind import StepKind

#: the three dwells of one test, in plan order
HALVES = ("pos", "zero", "neg")


def _read_back_fields(events: Sequence[dict[str, Any]]) -> dict[str, float]:
    """step_id → the field the coil read back when it was set (the last attempt's)."""
    found: dict[str, float] = {}
    for event in events:
        if event.get("event") == JournalEvent.COIL_FIELD and event.get("when") == "set":
            found[str(event["step_id"])] = float(event["field_t"])
    return found


@dataclass(frozen=True)
class MagneticEntry:
    """One magnetic test: its three dwells, the slope and its budget (results.json
    ``magnetic[i]``)."""

    test: str
    steps: tuple[str, ...]
    setpoint_c: float
    coil_axis: str | None
    field_t: tuple[float, ...]
    bias_dph: tuple[float, ...]
    u_bias_dph: tuple[float, ...]
    result: MagneticSensitivity
    uncertainty: Uncertainty

    def to_json(self) -> dict[str, Any]:
        return {"test": self.test, "steps": list(self.steps), "setpoint_c": self.setpoint_c,
                "coil_axis": self.coil_axis, "field_t": list(self.field_t),
                "bias_dph": list(self.bias_dph), "u_bias_dph": list(self.u_bias_dph),
                "field_span_t": max(self.field_t) - min(self.field_t),
                "sensitivity_dph_per_t": self.result.sensitivity_dph_per_t,
                "bias_at_zero_dph": self.result.bias_at_zero_dph, "grade": self.result.grade(),
                "uncertainty": self.uncertainty.to_json()}


def magnetic_section(steps: Sequence, plan: dict[str, Any], events: Sequence[dict[str, Any]],
                     nominal_sf: float, notes: list[str]) -> tuple[MagneticEntry, ...] | None:
    """One entry per magnetic test (``steps``: the report's StepSummary list), or None."""
    coil = (plan.get("station") or {}).get("coil") or {}
    u_coil_rel = float(coil.get("u_constant_rel") or 0.0)
    fields = _read_back_fields(events)
    groups: dict[str, dict[str, Any]] = {}
    for summary in steps:
        if summary.step.kind == StepKind.MAGNETIC:
            head, _, half = summary.step.step_id.rpartition(".")
            groups.setdefault(head, {})[half] = summary
    out = []
    for head, by_half in groups.items():
        if set(by_half) != set(HALVES):
            notes.append(f"magnetic {head}: needs its +B, 0 and -B dwells; has {sorted(by_half)}")
            continue
        dwells = [by_half[h] for h in HALVES]
        field = [fields.get(d.step.step_id, d.step.field_t) for d in dwells]
        bias = [d.output_mean / nominal_sf * 3600.0 for d in dwells]
        u_bias = [d.output_sem / abs(nominal_sf) * 3600.0 for d in dwells]
        dofs = [d.sem_dof for d in dwells]
        if any(f is None for f in field) or not all(math.isfinite(u) and u > 0 for u in u_bias):
            notes.append(f"magnetic {head}: a dwell has no field or no type A uncertainty")
            continue
        try:
            result = sensitivity(field, bias, u_bias)
        except ValueError as exc:
            notes.append(f"magnetic {head}: {exc}")
            continue
        out.append(_entry(head, dwells, field, bias, u_bias, dofs, result, u_coil_rel, coil))
    return tuple(out) or None


def _entry(head: str, dwells, field, bias, u_bias, dofs, result, u_coil_rel: float,
           coil: dict[str, Any]) -> MagneticEntry:
    """The entry: the dwells, the slope and its budget (type A per dwell, B of the coil)."""
    # each dwell's sensitivity coefficient is its weight in the weighted-LS slope (±1/(2B)
    # and 0 for a symmetric design with equal u): Σ (c_i u_i)² is the fit's own slope variance
    weights = _slope_weights(field, u_bias)
    budget = [Contribution(f"bias at {f:+.4g} T", d.step.step_id, EvalType.A, "normal",
                           u, w, abs(w) * u, dof)
              for d, f, u, w, dof in zip(dwells, field, u_bias, weights, dofs, strict=True)]
    budget.append(Contribution("coil constant", "station coil.u_constant_rel", EvalType.B,
                               "normal", u_coil_rel, result.sensitivity_dph_per_t,
                               abs(result.sensitivity_dph_per_t) * u_coil_rel, math.inf))
    u = combine(result.sensitivity_dph_per_t, budget)
    return MagneticEntry(head, tuple(d.step.step_id for d in dwells), dwells[0].step.setpoint_c,
                         coil.get("axis"), tuple(field), tuple(bias), tuple(u_bias), result, u)


def _slope_weights(field: Sequence[float], u_bias: Sequence[float]) -> list[float]:
    """∂slope/∂bias_i of the weighted LS line (bias on field): w_i (B_i - B̄_w) / Σ w_j (B_j - B̄_w)²."""
    w = [1.0 / u**2 for u in u_bias]
    mean = sum(wi * b for wi, b in zip(w, field, strict=True)) / sum(w)
    sxx = sum(wi * (b - mean) ** 2 for wi, b in zip(w, field, strict=True))
    return [wi * (b - mean) / sxx for wi, b in zip(w, field, strict=True)]
