"""The numbers a run's results.json contributes to the lab's database.

Which metrics, and their database names (units in the name), are the catalogue's
(``metrology/metrics.py``: ``DATABASE_METRICS``). Its
uncertainty is taken from what the report provides: the report's
``uncertainty`` section (keyed by the value's path: ``scale_factor_ls.sf``,
``asymmetry_ppm``, ``allan.fit.N_deg_per_rth``, ``bias@25``), else a mapping
``{"value": …, "u": …, "U": …}`` in place of the number, or ``<key>_u``/``<key>_U``
siblings, or for the Allan terms the fit's standard error. Where none exists the
uncertainty is NULL, never a guess.

The headline ``bias_dph`` is the bias at the report's reference temperature (the one the
scale factor and the temperature coefficients refer to): the static bias measured there,
or interpolated linearly between the two temperatures around it, with u and U the same
weighted sums of theirs (an upper bound whatever the correlation between the two). Outside
the measured temperatures there is no headline bias: extrapolating one is a guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gyrocal.metrology.metrics import (
    DATABASE_METRICS,
    HEADLINE_BIAS_DB_NAME,
    metric_parent,
    reported_uncertainty,
)
from gyrocal.metrology.metrics import as_number as _number


@dataclass(frozen=True)
class MetricValue:
    metric: str
    value: float
    u: float | None      # standard uncertainty
    U: float | None      # expanded uncertainty (coverage factor per the report)  # noqa: N815


def metric_values(results: dict[str, Any]) -> list[MetricValue]:
    """Every catalogue metric with a database name that ``results`` holds, then the headline bias."""
    out = []
    for name, metric in DATABASE_METRICS.items():
        container = metric_parent(results, metric)
        if container is None:
            continue
        key = metric.path[-1]
        raw = container.get(key)
        u, U = reported_uncertainty(results, metric)  # noqa: N806 - GUM's symbol
        if isinstance(raw, dict):                       # {"value": …, "u": …, "U": …}
            value = _number(raw.get("value"))
            u = u if u is not None else _number(raw.get("u"))
            U = U if U is not None else _number(raw.get("U"))  # noqa: N806
        else:
            value = _number(raw)
            u = u if u is not None else _number(container.get(f"{key}_u"))
            U = U if U is not None else _number(container.get(f"{key}_U"))  # noqa: N806
        if value is None:
            continue
        if u is None and metric.noise_term is not None:
            fit_u = (results["allan"].get("fit_uncertainty") or {}).get(key) or {}
            u = _number(fit_u.get("stderr"))
        out.append(MetricValue(name, value, u, U))
    headline = bias_at_reference(results)
    if headline is not None:
        out.append(headline)
    return out


def bias_at_reference(results: dict[str, Any]) -> MetricValue | None:
    """The static bias at the reference temperature (see the module's docstring)."""
    reference = _number(results.get("reference_temp_c"))
    entries = [e for e in results.get("bias") or [] if isinstance(e, dict)
               and _number(e.get("temp_c")) is not None and _number(e.get("bias_dph")) is not None]
    if reference is None or not entries:
        return None
    entries.sort(key=lambda e: e["temp_c"])
    for entry in entries:
        if abs(entry["temp_c"] - reference) < 1e-9:
            return MetricValue(HEADLINE_BIAS_DB_NAME, float(entry["bias_dph"]), _number(entry.get("u")),
                               _number(entry.get("U")))
    below = [e for e in entries if e["temp_c"] < reference]
    above = [e for e in entries if e["temp_c"] > reference]
    if not below or not above:
        return None
    lo, hi = below[-1], above[0]
    w = (reference - lo["temp_c"]) / (hi["temp_c"] - lo["temp_c"])
    value = (1 - w) * lo["bias_dph"] + w * hi["bias_dph"]

    def weighted(key: str) -> float | None:
        a, b = _number(lo.get(key)), _number(hi.get(key))
        return None if a is None or b is None else (1 - w) * a + w * b

    return MetricValue(HEADLINE_BIAS_DB_NAME, value, weighted("u"), weighted("U"))
