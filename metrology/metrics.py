"""The one catalogue of results.json metrics: names, units, what each needs, how to read it.

Acceptance limits are checked by QA the morning after; a misspelt metric or a
limit on something the procedure never measures must fail at ``gyrocal
validate``, not after sixteen hours on the table. Names are the key paths of
``report/results.json`` in ``/work/shared/spec/interfaces.md``.

Every user of a metric takes it from here: procedure validation (the limits a
procedure may set), the report's limit evaluation (``reports/results.py``), the
certificate's table of single figures, the runs database's metric names
(``reports/runs/metrics.py``) and the physical-sense checks. A value is read from
a results mapping only through :func:`metric_value` / :func:`metric_number`, so
the path walk exists once.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum

from gyrocal.models.noise_terms import NOISE_TERMS


class Need(str, Enum):
    """What a procedure must measure for a metric to be computed (a metric's ``needs``).

    The one spelling of these words: procedure validation (what the sequence will
    measure), the report (what the completed steps measured) and the acceptance
    evaluation compare them as members of this enum.
    """

    SWEEP = "sweep"
    SWEEP_TEMPS = "sweep_temps"
    BIAS_TEMPS = "bias_temps"
    ALLAN = "allan"
    THRESHOLD = "threshold"
    RATE_LIMIT_POSITIVE = "rate_limit_positive"
    RATE_LIMIT_NEGATIVE = "rate_limit_negative"
    FREQUENCY_RESPONSE = "frequency_response"
    TURN_ON = "turn_on"
    TURN_ON_REPEATABILITY = "turn_on_repeatability"

    @property
    def text(self) -> str:
        """What the procedure must contain, in a sentence's words."""
        return NEEDS_TEXT[self]

    @classmethod
    def rate_limit(cls, sign: float) -> Need:
        """The rate-limit walk of one direction (sign of the rate)."""
        return cls.RATE_LIMIT_POSITIVE if sign > 0 else cls.RATE_LIMIT_NEGATIVE


@dataclass(frozen=True)
class Certified:
    """How the calibration certificate prints a metric: its row, its words, its unit."""

    row: int
    label: str
    unit: str


@dataclass(frozen=True)
class Trend:
    """How the runs database's history plot shows a metric: its panel and axis label."""

    row: int
    label: str          # words and unit


@dataclass(frozen=True)
class Metric:
    key: str               # key path in results.json
    unit: str | None       # canonical unit; None when it is the unit under test's own output unit
    needs: Need            # what the sequence must contain
    #: the sign is physical: a max limit bounds the magnitude (every other metric with a
    #: max limit is a size or a spread, and a negative value of it is impossible)
    signed: bool = False
    #: the name of the metric in the lab's runs database (its unit in the name), if stored
    db_name: str | None = None
    #: the certificate's row for it, when it is a certified single figure
    certified: Certified | None = None
    #: the history plot's panel for it (runs database), when one is drawn
    trend: Trend | None = None

    @property
    def path(self) -> tuple[str, ...]:
        return tuple(self.key.split("."))

    @property
    def field(self) -> str:
        """The key of the value in its section (the path's last part)."""
        return self.path[-1]

    @property
    def noise_term(self) -> str | None:
        """The ``allan.fit`` key of a fitted noise term (Q_arcsec…), else None."""
        return self.key.removeprefix("allan.fit.") if self.key.startswith("allan.fit.") else None


_IEEE = "IEEE Std 952 / 1431"
_NOISE_TRENDS = {"N": Trend(7, "angle random walk\n(deg/√h)"),
                 "B": Trend(8, "bias instability\n(deg/h)")}

# Each metric is named here once; code that needs a particular one (the uncertainty budgets,
# the headline figures of a section) takes it by this name, never by re-spelling its key.
NONLINEARITY_RMS = Metric(
    "nonlinearity.rms_pct", "%", Need.SWEEP, db_name="nonlinearity_rms_pct",
    certified=Certified(2, "Nonlinearity (RMS of SF over rates)", "%"),
    trend=Trend(5, "SF nonlinearity\nRMS (%)"))
NONLINEARITY_MAX = Metric(
    "nonlinearity.max_ppm_fs", "ppm", Need.SWEEP, db_name="nonlinearity_max_ppm_fs",
    certified=Certified(3, "Nonlinearity (max residual)", "ppm of full scale"))
ASYMMETRY = Metric(
    "asymmetry_ppm", "ppm", Need.SWEEP, signed=True, db_name="asymmetry_ppm",
    certified=Certified(4, "Scale-factor asymmetry", "ppm"), trend=Trend(6, "SF asymmetry\n(ppm)"))
SF_LS = Metric(
    "scale_factor_ls.sf", None, Need.SWEEP, db_name="sf",
    certified=Certified(1, "Scale factor, LS line at the reference temperature", "output/(deg/s)"),
    trend=Trend(1, "scale factor\n(output/(deg/s))"))
SF_LS_BIAS = Metric("scale_factor_ls.bias", None, Need.SWEEP, signed=True, db_name="bias_dps_ls")
SF_INSTABILITY = Metric(
    "sf_temperature.instability_pct", "%", Need.SWEEP_TEMPS, db_name="sf_instability_pct",
    certified=Certified(6, "SF temperature instability", "%"))
SF_TEMPCO = Metric(
    "sf_temperature.sensitivity_ppm_per_c", "ppm/°C", Need.SWEEP_TEMPS, signed=True,
    db_name="sf_tempco_ppm_per_c", certified=Certified(5, "SF temperature sensitivity", "ppm/°C"),
    trend=Trend(2, "SF temp. coeff.\n(ppm/°C)"))
BIAS_TEMPCO = Metric(
    "bias_temperature.sensitivity_dph_per_c", "deg/h/°C", Need.BIAS_TEMPS, signed=True,
    db_name="bias_tempco_dph_per_c",
    certified=Certified(7, "Bias temperature sensitivity", "deg/h per °C"),
    trend=Trend(4, "bias temp. coeff.\n(deg/h/°C)"))
#: the noise terms, by their ``allan.fit`` key; in the database under their model-file
#: names (models/noise_terms.py)
NOISE_METRICS: dict[str, Metric] = {
    t.fit_key: Metric(f"allan.fit.{t.fit_key}", t.unit, Need.ALLAN, db_name=t.model_key,
                      trend=_NOISE_TRENDS.get(t.symbol)) for t in NOISE_TERMS}
MARKOV_SIGMA = Metric("allan.fit.markov.sigma_dph", "deg/h", Need.ALLAN)
MARKOV_TAU = Metric("allan.fit.markov.tau_s", "s", Need.ALLAN)
THRESHOLD = Metric("threshold.threshold_dps", "deg/s", Need.THRESHOLD, certified=Certified(
    8, f"Threshold, {_IEEE} (smallest resolved increment at zero rate; U from the "
       "increment grid)", "deg/s"))
RESOLUTION = Metric("threshold.resolution_dps", "deg/s", Need.THRESHOLD, certified=Certified(
    9, f"Resolution, {_IEEE} (smallest resolved increment at the set rates; U from "
       "the increment grid)", "deg/s"))
MAX_RATE_POSITIVE = Metric(
    "rate_limits.max_positive_dps", "deg/s", Need.RATE_LIMIT_POSITIVE, certified=Certified(
        10, f"Maximum input rate, positive, {_IEEE} (U from the rate walk)", "deg/s"))
MAX_RATE_NEGATIVE = Metric(
    "rate_limits.max_negative_dps", "deg/s", Need.RATE_LIMIT_NEGATIVE, certified=Certified(
        11, f"Maximum input rate, negative, {_IEEE} (U from the rate walk)", "deg/s"))
BANDWIDTH = Metric(
    "frequency_response.bandwidth_hz", "Hz", Need.FREQUENCY_RESPONSE, certified=Certified(
        12, f"Bandwidth (−3 dB), {_IEEE} frequency response test (table in synthesis "
            "mode; U from the sine fits and the interpolation)", "Hz"))
PHASE = Metric(
    "frequency_response.phase_deg", "deg", Need.FREQUENCY_RESPONSE, certified=Certified(
        13, f"Phase at the stated frequency, {_IEEE} frequency response test (U from the "
            "sine fits and the sample timing)", "deg"))
TURN_ON_TIME = Metric("turn_on.time_to_first_data_s", "s", Need.TURN_ON, certified=Certified(
    14, f"Turn-on time, {_IEEE} turn-on test (output-on to first valid data; U from "
        "the poll interval)", "s"))
WARMUP_TIME_TO_BAND = Metric("turn_on.time_to_band_s", "s", Need.TURN_ON, certified=Certified(
    17, f"Warm-up time to the stated band of the settled bias, {_IEEE}", "s"))
WARMUP_TAU = Metric("turn_on.warmup_tau_s", "s", Need.TURN_ON, certified=Certified(
    15, f"Warm-up time constant, {_IEEE} warm-up test (fit of b∞ + A·e^(−t/τ))", "s"))
WARMUP_AMPLITUDE = Metric("turn_on.warmup_amplitude_dph", "deg/h", Need.TURN_ON,
                          certified=Certified(16, f"Warm-up amplitude, {_IEEE} warm-up test",
                                              "deg/h"))
TURN_ON_REPEATABILITY = Metric(
    "turn_on_repeatability.std_dph", "deg/h", Need.TURN_ON_REPEATABILITY, certified=Certified(
        18, f"Turn-on-to-turn-on bias repeatability, {_IEEE} (standard deviation of the "
            "cycles' biases; U from N)", "deg/h"))

#: The catalogue: key path → metric, in catalogue order.
METRICS: dict[str, Metric] = {m.key: m for m in (
    NONLINEARITY_RMS, NONLINEARITY_MAX, ASYMMETRY, SF_LS, SF_LS_BIAS, SF_INSTABILITY, SF_TEMPCO,
    BIAS_TEMPCO, *NOISE_METRICS.values(), MARKOV_SIGMA, MARKOV_TAU, THRESHOLD, RESOLUTION,
    MAX_RATE_POSITIVE, MAX_RATE_NEGATIVE, BANDWIDTH, PHASE, TURN_ON_TIME, WARMUP_TIME_TO_BAND,
    WARMUP_TAU, WARMUP_AMPLITUDE, TURN_ON_REPEATABILITY)}

#: The runs database's one metric that is not a results.json key: the static bias at
#: the reference temperature, interpolated between the two around it
#: (``reports/runs/metrics.py``), in deg/h.
HEADLINE_BIAS_DB_NAME = "bias_dph"
_HEADLINE_BIAS_TREND = Trend(3, "bias at ref. temp.\n(deg/h)")

#: Metrics stored in the runs database, by their database name (catalogue order).
DATABASE_METRICS: dict[str, Metric] = {m.db_name: m for m in METRICS.values() if m.db_name}

#: The history plot's panels: database name → axis label, in panel order.
TRENDS: dict[str, str] = {name: trend.label for name, trend in sorted(
    [*((m.db_name, m.trend) for m in DATABASE_METRICS.values() if m.trend and m.db_name),
     (HEADLINE_BIAS_DB_NAME, _HEADLINE_BIAS_TREND)], key=lambda item: item[1].row)}

#: Certified single figures in the certificate's row order.
CERTIFIED_METRICS: tuple[Metric, ...] = tuple(sorted(
    (m for m in METRICS.values() if m.certified is not None),
    key=lambda m: m.certified.row if m.certified is not None else 0))

NEEDS_TEXT: dict[Need, str] = {
    Need.SWEEP: "an sf_sweep test",
    Need.SWEEP_TEMPS: "sf_sweep tests at two or more temperatures",
    Need.BIAS_TEMPS: "static or allan tests at two or more temperatures",
    Need.ALLAN: "an allan test",
    Need.THRESHOLD: "a threshold test",
    Need.RATE_LIMIT_POSITIVE: "a rate_limit test walking the positive direction",
    Need.RATE_LIMIT_NEGATIVE: "a rate_limit test walking the negative direction",
    Need.FREQUENCY_RESPONSE: "a frequency_response test",
    Need.TURN_ON: "a turn_on test",
    Need.TURN_ON_REPEATABILITY: "a turn_on_repeatability test",
}


def metric_parent(results: Mapping[str, object], metric: Metric) -> Mapping[str, object] | None:
    """The mapping of ``results`` that holds the metric's value (None when a level is missing)."""
    node: object = results
    for part in metric.path[:-1]:
        node = node.get(part) if isinstance(node, Mapping) else None
    return node if isinstance(node, Mapping) else None


def metric_value(results: Mapping[str, object], metric: Metric) -> object:
    """What results.json holds at the metric's key path; None when any part is missing/null."""
    parent = metric_parent(results, metric)
    return None if parent is None else parent.get(metric.path[-1])


def as_number(value: object) -> float | None:
    """A JSON number as a float; None for null, booleans, strings, mappings."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def metric_number(results: Mapping[str, object], metric: Metric) -> float | None:
    """The metric's finite number in ``results``; None when absent, null, non-numeric or NaN/inf."""
    number = as_number(metric_value(results, metric))
    return number if number is not None and math.isfinite(number) else None


def reported_uncertainty(results: Mapping[str, object], metric: Metric
                         ) -> tuple[float | None, float | None]:
    """u and U the report's ``uncertainty`` section gives the metric (keyed by its path)."""
    section = results.get("uncertainty")
    entry = section.get(metric.key) if isinstance(section, Mapping) else None
    if not isinstance(entry, Mapping):
        return None, None
    return as_number(entry.get("u")), as_number(entry.get("U"))


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

