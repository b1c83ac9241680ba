"""What the discrepancy workflow reports: the named effects, each search round, the gaps.

Typed results handed from the passes (workflow.py) to the report (html.py,
command.py); ``DiscrepancyResult.to_json`` writes the discrepancy JSON.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gyrocal.analysis.discrepancy.gap import Metric, SegmentGeometry
from gyrocal.analysis.discrepancy.lookalikes import LookAlike
from gyrocal.analysis.discrepancy.noise_model import NoiseEstimate, NoiseModel
from gyrocal.analysis.discrepancy.periodic import PeriodicScan
from gyrocal.analysis.discrepancy.probes import Probe, ProbeKind
from gyrocal.analysis.discrepancy.segments import Bins, Segments
from gyrocal.models.gyro_model import GyroModel

#: Family-wise false-positive rate of the acceptance threshold in the first pass; pass k
#: uses ALPHA/k, so an extra effect after a real one is no easier to "find" than a first.
#: The threshold is calibrated on data simulated from the *estimated* noise model; the
#: real effect-free distribution is slightly heavier (the noise terms are estimates), so
#: nominal 5 % gave 5.7 % on 140 simulated controls and nominal 3 % gave 4.0 % on 200.
#: 2 % keeps the measured rate under the 5 % target with margin (docs/discrepancy-validation.md).
ALPHA = 0.02



@dataclass(frozen=True)
class FoundEffect:
    name: str
    parameters: dict[str, float]
    probability: float
    look_alikes: list[LookAlike]
    separating_experiment: str
    score: float
    delta_chi2: float
    threshold: float

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "probability": float(self.probability),
            "look_alikes": [{"name": a.name, "probability": float(a.probability)}
                            for a in self.look_alikes],
            "separating_experiment": self.separating_experiment,
            "score": float(self.score),
            "delta_chi2": float(self.delta_chi2),
            "threshold": float(self.threshold),
        }


@dataclass(frozen=True)
class Iteration:
    """What one pass scored, for the report: every effect's score and the threshold."""

    scores: dict[str, float]
    delta_chi2: dict[str, float]
    threshold: float
    accepted: str | None
    probes: list[Probe]

    @property
    def step(self) -> Probe | None:
        """The bias-step probe (kept under its old JSON key)."""
        return next((p for p in self.probes if p.kind is ProbeKind.BIAS_STEP), None)


@dataclass
class DiscrepancyResult:
    found: list[FoundEffect]
    unexplained: bool
    where: str
    metrics: dict[str, Metric]
    primary: str
    input_model: GyroModel
    updated_model: GyroModel
    noise: NoiseEstimate
    iterations: list[Iteration]
    # material for the plots
    bins: Bins
    segments: Segments
    seg_ids_of_geometry: np.ndarray
    geometry: SegmentGeometry
    resid_before_bins: np.ndarray
    resid_after_bins: np.ndarray
    signals: dict[str, np.ndarray]
    scan_before: PeriodicScan | None
    scan_after: PeriodicScan | None
    noise_before: NoiseModel
    t0_s: float
    notes: list[str] = field(default_factory=list)
    #: each named effect → the key in ``metrics`` of its own headline gap (own_gap.py)
    effect_gaps: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict:
        gap = self.metrics[self.primary]
        return {
            "found": [f.to_json() for f in self.found],
            "unexplained": bool(self.unexplained),
            "where": self.where,
            "gap": {"metric": self.primary, **gap.to_json()},
            "metrics": {name: m.to_json() for name, m in self.metrics.items()},
            "effect_gaps": dict(self.effect_gaps),
            "threshold": {"alpha": ALPHA,
                          "per_iteration": [it.threshold for it in self.iterations]},
            "scores": [{"effects": it.scores, "threshold": it.threshold, "accepted": it.accepted,
                        "step_probe": None if it.step is None else {
                            "time_s": it.step.time_s, "size_dph": it.step.size_dph,
                            "score": it.step.score, "threshold": it.step.threshold},
                        "probes": [{"kind": p.kind.value, "where": p.where, "size": p.size,
                                    "description": p.describe(),
                                    "delta_chi2": p.delta_chi2, "score": p.score,
                                    "threshold": p.threshold, "candidates": p.n_candidates}
                                   for p in it.probes]}
                       for it in self.iterations],
            "noise_model": {**self.noise.model.__dict__, "source": self.noise.source,
                            "quiet_seconds": self.noise.quiet_seconds},
            "notes": self.notes,
        }
