"""results dict → report.html: one self-contained page for someone who was not there.

Autoescape is on for the whole template: procedure names, serials,
operator names and instrument replies are user-supplied text, and a
report opened in QA's browser must not run what a YAML file contained.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import jinja2

from gyrocal.metrology.gum import round_to_uncertainty
from gyrocal.record.event_text import describe_event
from gyrocal.reports.labels import ALLAN_TERMS, acceptance_unit, compensation_labels
from gyrocal.reports.plots import all_plots
from gyrocal.reports.report_template import REPORT_TEMPLATE


def _fmt(value: Any, digits: int = 4) -> str:
    """Numbers to ``digits`` significant figures; null shows as 'n/a'."""
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


@cache
def _template() -> jinja2.Template:
    """The page's template, compiled once per process: compiling it is ~60 ms of CPU, and a
    process that builds more than one report (a test worker makes hundreds of dry runs)
    compiled the same constant text again for each. A compiled
    jinja2 template renders from any thread (it keeps no state between renders)."""
    environment = jinja2.Environment(autoescape=True, undefined=jinja2.ChainableUndefined,
                                     trim_blocks=True, lstrip_blocks=True)
    return environment.from_string(REPORT_TEMPLATE)


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
    template = _template()
    acceptance = results.get("acceptance") or []
    return template.render(r=results, plots=all_plots(results), fmt=_fmt, vu=_value_and_u,
                           terms=ALLAN_TERMS, compensation=compensation_labels(results),
                           unit_of=acceptance_unit,
                           describe=describe_event,
                           all_pass=all(a.get("pass") for a in acceptance))
