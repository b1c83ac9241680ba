"""results.json ``allan``, typed: the curve of the longest hold and its noise-term fit.

The fitted terms stay typed (:class:`~gyrocal.analysis.allan.noise_fit.NoiseFit`) until
the file is written, so the uncertainty of each term is taken from the fit itself.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gyrocal.analysis.allan.deviation import AllanResult
from gyrocal.analysis.allan.noise_fit import NoiseFit
from gyrocal.analysis.allan.summary import curve_json, fit_uncertainty_json, identifiability_json
from gyrocal.metrology.gum import Uncertainty


@dataclass(frozen=True)
class AllanSection:
    """The curve (deg/h, input-referred), its fit and which record it came from."""

    curve: AllanResult
    fit: NoiseFit
    step_id: str
    temp_c: float
    n_samples: int
    rate_hz: float

    def to_json(self, u: Mapping[str, Uncertainty] | None = None) -> dict[str, Any]:
        """``u``: each fitted term's budget (``allan.fit`` key → Uncertainty), when computed."""
        out = curve_json(self.curve, self.fit) | {
            "fit_uncertainty": fit_uncertainty_json(self.fit), "fit_dof": self.fit.dof,
            **identifiability_json(self.fit),
            "model_adev_dph": self.fit.model_adev(self.curve.tau_s).tolist(),
            "step_id": self.step_id, "temp_c": self.temp_c,
            "duration_s": self.n_samples / self.rate_hz, "n_samples": self.n_samples,
            "rate_hz": self.rate_hz, "method": self.curve.method,
        }
        if u is not None:
            out["uncertainty"] = {name: {"value": unc.value} | unc.to_json()
                                  for name, unc in u.items()}
        return out
