"""The ``tilt_linearity`` block of results.json: an inclinometer's static test, fitted.

A ``tilt_linearity`` test plans one step per angle point (``….tilt.+15deg``) and
a zero-stability hold at 0 (``….tilt.zero``), the table (axis horizontal) held
at each angle as the indexing head. Per point the mean of the sensitive
inclinometer channel (``incl_x_g``) and of the one across it (``incl_y_g``) is
taken; ``tilt_linearity.py`` fits the sensitivity and linearity by least squares
against g·sin θ (g: the station's local gravity in g), the lateral sensitivity
from the y channel's slope, and the zero stability as the standard deviation of
the 1-s means of the zero hold over its stated duration, in g of input.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.analysis.environment.tilt_linearity import (
    LinearityResult,
    lateral_sensitivity_pct,
    linearity,
    zero_stability,
)
from gyrocal.record.plan_record import PlanRecord
from gyrocal.record.samples import RunSamples
from gyrocal.record.step_kind import StepKind

SENSITIVE, LATERAL = "incl_x_g", "incl_y_g"


def _columns(run: RunSamples, step_id: str) -> dict[str, np.ndarray]:
    """The two inclinometer channels of a step's counted attempt, good samples only."""
    logged = run.step(step_id, (SENSITIVE, LATERAL))
    if SENSITIVE not in logged or LATERAL not in logged:
        raise ValueError(f"step {step_id} has no {SENSITIVE} column (the gyro datagram carries "
                         "no inclinometers)")
    return {SENSITIVE: logged[SENSITIVE], LATERAL: logged[LATERAL]}


@dataclass(frozen=True)
class TiltEntry:
    """One tilt_linearity test fitted: an entry of results.json ``tilt_linearity``."""

    test: str
    angles_deg: tuple[float, ...]
    output_g: tuple[float, ...]             # the sensitive channel's mean per angle
    lateral_output_g: tuple[float, ...]     # the channel across it
    gravity_g: float
    fit: LinearityResult
    lateral_sensitivity_pct: float
    zero_stability_g: float
    zero_stability_over_s: float

    def to_json(self) -> dict[str, Any]:
        fit = self.fit
        return {"test": self.test, "angles_deg": list(self.angles_deg),
                "output_g": list(self.output_g), "lateral_output_g": list(self.lateral_output_g),
                "gravity_g": self.gravity_g,
                "sensitivity": fit.sensitivity, "u_sensitivity": fit.u_sensitivity,
                "zero_output_g": fit.zero_output, "linearity_pct_fs": fit.linearity_pct_fs,
                "residuals_g": [float(r) for r in fit.residuals],
                "lateral_sensitivity_pct": self.lateral_sensitivity_pct,
                "zero_stability_g": self.zero_stability_g,
                "zero_stability_over_s": self.zero_stability_over_s,
                "zero_stability_definition": "std of the 1-s means of the zero hold / sensitivity"}


def tilt_section(run_dir: Path, record: PlanRecord, events: list[dict[str, Any]],
                 gravity_g: float, notes: list[str]) -> tuple[TiltEntry, ...] | None:
    """One entry per tilt_linearity test, or None when the plan has none."""
    done = RunSamples(run_dir, events)
    groups: dict[str, list] = {}
    for step in record.steps:
        if step.kind == StepKind.TILT:
            groups.setdefault(step.step_id.rpartition(".")[0], []).append(step)
    out = []
    for head, steps in groups.items():
        missing = [s.step_id for s in steps if s.step_id not in done]
        if missing:
            notes.append(f"tilt linearity {head}: not completed: {', '.join(missing)}")
            continue
        try:
            out.append(_entry(done, head, steps, record.sample_rate_hz, gravity_g))
        except ValueError as exc:
            notes.append(f"tilt linearity {head}: {exc}")
    return tuple(out) or None


def _entry(run: RunSamples, head: str, steps, fs_hz: float, gravity_g: float) -> TiltEntry:
    points = [s for s in steps if not s.step_id.endswith(".zero")]
    zero = next(s for s in steps if s.step_id.endswith(".zero"))
    means = [{k: float(np.mean(v)) for k, v in _columns(run, s.step_id).items()}
             for s in points]
    angles = [float(s.angle_deg) for s in points]
    fit = linearity(angles, [m[SENSITIVE] for m in means], gravity_g)
    lateral = lateral_sensitivity_pct(angles, [m[LATERAL] for m in means], fit.sensitivity,
                                      gravity_g)
    held = _columns(run, zero.step_id)[SENSITIVE]
    per_s = max(1, int(round(fs_hz)))
    seconds = held[: held.size // per_s * per_s].reshape(-1, per_s).mean(axis=1)
    return TiltEntry(head, tuple(angles), tuple(m[SENSITIVE] for m in means),
                     tuple(m[LATERAL] for m in means), gravity_g, fit, lateral,
                     zero_stability(seconds, fit.sensitivity), zero.duration_s)
