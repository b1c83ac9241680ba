"""results dict → report.html: one self-contained page for someone who was not there.

Autoescape is on for the whole template: procedure names, serials,
operator names and instrument replies are user-supplied text, and a
report opened in QA's browser must not run what a YAML file contained.
"""

from __future__ import annotations

from typing import Any

import jinja2

from gyrocal.models.noise_terms import NOISE_TERMS
from gyrocal.orchestrator.metrics import METRICS
from gyrocal.orchestrator.watch.event_text import describe_event
from gyrocal.reports.gum import round_to_uncertainty
from gyrocal.reports.plots import all_plots
from gyrocal.reports.report_template import REPORT_TEMPLATE

#: Allan rows: (results key, what a reader sees, unit)
_TERMS = tuple((t.fit_key, f"{t.symbol} — {t.name}", t.unit) for t in NOISE_TERMS)

#: compensation tables (results ``compensation.tables`` keys): what they hold and in what unit
_COMPENSATION = {"bias_dph": ("Bias over temperature", "deg/h"),
                 "sf": ("Scale factor over temperature", None)}


def _metric_unit(metric: str, given: str | None, output_units: str) -> str:
    """The unit an acceptance value and limit are in: the procedure's, else the metric's."""
    if given:
        return given
    spec = METRICS.get(metric)
    if spec is None:
        return ""
    return spec.unit if spec.unit is not None else output_units


def _fmt(value: Any, digits: int = 4) -> str:
    """Numbers to ``digits`` significant figures; null shows as 'n/a'."""
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _environment() -> jinja2.Environment:
    return jinja2.Environment(autoescape=True, undefined=jinja2.ChainableUndefined,
                              trim_blocks=True, lstrip_blocks=True)


def _value_and_u(value: Any, expanded: Any) -> str:
    """``value ± U`` with the digits U supports (GUM 7.2.6), or the value alone."""
    if not isinstance(value, (int, float)):
        return "—"
    if not isinstance(expanded, (int, float)):
        return _fmt(value)
    shown, u_text = round_to_uncertainty(float(value), float(expanded))
    return f"{shown} ± {u_text}"


def render_html(results: dict[str, Any]) -> str:
    """The report page with its plots embedded as base64 PNG."""
    template = _environment().from_string(REPORT_TEMPLATE)
    acceptance = results.get("acceptance") or []
    output_units = str((results.get("unit_under_test") or {}).get("output_units") or "")
    compensation = {key: (label, unit or f"{output_units} per deg/s")
                    for key, (label, unit) in _COMPENSATION.items()}
    return template.render(r=results, plots=all_plots(results), fmt=_fmt, vu=_value_and_u,
                           terms=_TERMS, compensation=compensation,
                           unit_of=lambda a: _metric_unit(str(a.get("metric")), a.get("unit"),
                                                          output_units),
                           describe=describe_event,
                           all_pass=all(a.get("pass") for a in acceptance))
