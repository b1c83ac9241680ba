"""The results.json metrics a procedure's acceptance limits may name, and what each needs.

Acceptance limits are checked by QA the morning after; a misspelt metric or a
limit on something the procedure never measures must fail at ``gyrocal
validate``, not after sixteen hours on the table. Names are the key paths of
``report/results.json`` in ``/work/shared/spec/interfaces.md``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from gyrocal.models.noise_terms import NOISE_TERMS


@dataclass(frozen=True)
class Metric:
    key: str               # key path in results.json
    unit: str | None       # canonical unit; None when it is the unit under test's own output unit
    needs: str             # what the sequence must contain: "sweep", "sweep_temps", "bias_temps", "allan"


_SWEEP, _SWEEP_TEMPS, _BIAS_TEMPS, _ALLAN = "sweep", "sweep_temps", "bias_temps", "allan"
_THRESHOLD = "threshold"
_FREQUENCY = "frequency_response"
_TURN_ON = "turn_on"
_REPEATABILITY = "turn_on_repeatability"
_LIMIT_POS, _LIMIT_NEG = "rate_limit_positive", "rate_limit_negative"

METRICS: dict[str, Metric] = {
    m.key: m
    for m in (
        Metric("nonlinearity.rms_pct", "%", _SWEEP),
        Metric("nonlinearity.max_ppm_fs", "ppm", _SWEEP),
        Metric("asymmetry_ppm", "ppm", _SWEEP),
        Metric("scale_factor_ls.sf", None, _SWEEP),
        Metric("scale_factor_ls.bias", None, _SWEEP),
        Metric("sf_temperature.instability_pct", "%", _SWEEP_TEMPS),
        Metric("sf_temperature.sensitivity_ppm_per_c", "ppm/°C", _SWEEP_TEMPS),
        Metric("bias_temperature.sensitivity_dph_per_c", "deg/h/°C", _BIAS_TEMPS),
        *(Metric(f"allan.fit.{t.fit_key}", t.unit, _ALLAN) for t in NOISE_TERMS),
        Metric("allan.fit.markov.sigma_dph", "deg/h", _ALLAN),
        Metric("allan.fit.markov.tau_s", "s", _ALLAN),
        Metric("threshold.threshold_dps", "deg/s", _THRESHOLD),
        Metric("threshold.resolution_dps", "deg/s", _THRESHOLD),
        Metric("rate_limits.max_positive_dps", "deg/s", _LIMIT_POS),
        Metric("rate_limits.max_negative_dps", "deg/s", _LIMIT_NEG),
        Metric("frequency_response.bandwidth_hz", "Hz", _FREQUENCY),
        Metric("frequency_response.phase_deg", "deg", _FREQUENCY),
        Metric("turn_on.time_to_first_data_s", "s", _TURN_ON),
        Metric("turn_on.time_to_band_s", "s", _TURN_ON),
        Metric("turn_on.warmup_tau_s", "s", _TURN_ON),
        Metric("turn_on.warmup_amplitude_dph", "deg/h", _TURN_ON),
        Metric("turn_on_repeatability.std_dph", "deg/h", _REPEATABILITY),
    )
}

NEEDS_TEXT = {
    _SWEEP: "an sf_sweep test",
    _SWEEP_TEMPS: "sf_sweep tests at two or more temperatures",
    _BIAS_TEMPS: "static or allan tests at two or more temperatures",
    _ALLAN: "an allan test",
    _THRESHOLD: "a threshold test",
    _LIMIT_POS: "a rate_limit test walking the positive direction",
    _LIMIT_NEG: "a rate_limit test walking the negative direction",
    _FREQUENCY: "a frequency_response test",
    _TURN_ON: "a turn_on test",
    _REPEATABILITY: "a turn_on_repeatability test",
}


def normalise_unit(unit: str) -> str:
    """Spelling-insensitive unit for comparison: ``°/√h`` == ``deg/sqrt(h)`` == ``deg/rt(h)``."""
    text = unit.strip().replace(" ", "").lower()
    for old, new in (
        ("percent", "%"), ("pct", "%"), ("℃", "c"), ("°c", "c"), ("degc", "c"),
        ("°", "deg"), ("dph", "deg/h"), ("√h", "rth"), ("sqrt(h)", "rth"), ("rt(h)", "rth"),
        ("^0.5", ""), ("″", "arcsec"), ('"', "arcsec"), ("^2", "2"),
    ):
        text = text.replace(old, new)
    text = re.sub(r"h/h$", "h2", text)     # deg/h/h == deg/h2
    return text


def units_match(given: str, metric: Metric) -> bool:
    return metric.unit is None or normalise_unit(given) == normalise_unit(metric.unit)


def metric_needs(metric: str) -> tuple[str, str] | None:
    """What an acceptance metric needs the run to have measured, and that need in words.

    The report's door to ``metrology/metrics.py`` (reports read runs only
    through the record): a limit whose need no completed step met is NOT EVALUATED.
    """
    spec = METRICS.get(metric)
    return None if spec is None else (spec.needs, NEEDS_TEXT[spec.needs])
