"""The stated uncertainty of a single figure whose section computes its own (threshold,
rate limits, frequency response, turn-on): results.json ``uncertainty[<metric key>]``.

The sweep, bias and Allan figures have full GUM budgets (``uncertainty.py``); these
figures have one dominant term each (a grid, a walk, a fit), stated with its method.
Each is keyed by its metric of the catalogue (``metrology/metrics.py``), never by a
re-spelled path.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gyrocal.metrology.metrics import Metric


@dataclass(frozen=True)
class StatedUncertainty:
    """One figure, its u and U = k·u, its unit, and how u was found."""

    metric: Metric
    value: float
    u: float | None
    U: float | None             # noqa: N815 - expanded uncertainty (GUM)
    k: float
    unit: str
    method: str

    def to_json(self) -> dict[str, Any]:
        return {"value": self.value, "u": self.u, "U": self.U, "k": self.k, "unit": self.unit,
                "method": self.method}


def keyed(stated: list[StatedUncertainty]) -> dict[str, StatedUncertainty]:
    """results.json ``uncertainty`` entries: metric key → stated uncertainty."""
    return {s.metric.key: s for s in stated}
