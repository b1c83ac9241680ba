"""The numbers a run's results.json contributes to the lab's database, one owner for their names.

Each metric is a path into results.json with its unit in its name. Its
uncertainty is taken from what the report provides: the GUM keys ``u`` (and
``U``, expanded) that the uncertainty work adds beside values — either a
mapping ``{"value": …, "u": …, "U": …}`` in place of the number, or
``<key>_u``/``<key>_U`` siblings — or, for the Allan terms, the fit's standard
error. Where none exists the uncertainty is NULL, never a guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gyrocal.models.noise_terms import NOISE_TERMS


@dataclass(frozen=True)
class MetricValue:
    metric: str
    value: float
    u: float | None      # standard uncertainty
    U: float | None      # expanded uncertainty (coverage factor per the report)  # noqa: N815


#: metric name → path in results.json (the last element is the key of the value)
METRICS: dict[str, tuple[str, ...]] = {
    "sf": ("scale_factor_ls", "sf"),
    "bias_dps_ls": ("scale_factor_ls", "bias"),
    "sf_tempco_ppm_per_c": ("sf_temperature", "sensitivity_ppm_per_c"),
    "sf_instability_pct": ("sf_temperature", "instability_pct"),
    "bias_tempco_dph_per_c": ("bias_temperature", "sensitivity_dph_per_c"),
    "nonlinearity_rms_pct": ("nonlinearity", "rms_pct"),
    "asymmetry_ppm": ("asymmetry_ppm",),
    # the noise terms under their model-file names (models/noise_terms.py)
    **{t.model_key: ("allan", "fit", t.fit_key) for t in NOISE_TERMS},
}


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def metric_values(results: dict[str, Any]) -> list[MetricValue]:
    out = []
    for name, path in METRICS.items():
        container: Any = results
        for key in path[:-1]:
            container = container.get(key) if isinstance(container, dict) else None
        if not isinstance(container, dict):
            continue
        key = path[-1]
        raw = container.get(key)
        u = U = None
        if isinstance(raw, dict):                       # {"value": …, "u": …, "U": …}
            value = _number(raw.get("value"))
            u, U = _number(raw.get("u")), _number(raw.get("U"))
        else:
            value = _number(raw)
            u, U = _number(container.get(f"{key}_u")), _number(container.get(f"{key}_U"))
        if value is None:
            continue
        if u is None and path[:2] == ("allan", "fit"):
            fit_u = (results["allan"].get("fit_uncertainty") or {}).get(key) or {}
            u = _number(fit_u.get("stderr"))
        out.append(MetricValue(name, value, u, U))
    bias = results.get("bias")
    if isinstance(bias, list):   # the bias at the first temperature (static), per date
        for entry in bias[:1]:
            value = _number(entry.get("bias_dph")) if isinstance(entry, dict) else None
            if value is not None:
                out.append(MetricValue("bias_dph", value, _number(entry.get("u")),
                                       _number(entry.get("U"))))
    return out
