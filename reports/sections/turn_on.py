"""Turn-on time and warm-up (IEEE Std 952 / IEEE Std 1431 turn-on and warm-up tests).

Each turn_on step is one power cycle (orchestrator/turn_on.py): the journal's
``unit_power_cycle`` event gives the output-on command's clock time and the poll interval
the first valid frame came in; the step's samples (clock ``t_s``) are the record from that
frame. Reported per step:

* time to first valid data: the middle of that interval after the output-on, with a
  rectangular u of half its width (u = poll/√12);
* the warm-up fit b∞ + A·e^(−t/τ) of analysis/thermal/warmup.py on t from the output-on, with the
  fit's type A u of τ and A;
* the time until the bias stays within ±band of its settled value: from the fit, with its
  u propagated, and the measured one (the last 1-s bin outside the band) beside it.

The bias is the output over the nominal scale factor, deg/h (Earth rate and the settled
bias are in b∞, which the band is taken about).

Turn-on-to-turn-on repeatability: the turn_on_cycle steps of one test, each logged after
its settling time; the bias of each is its record's mean, the repeatability their standard
deviation with u = s/√(2(N−1)); the in-run bias stability beside it is the pooled standard
deviation of the 1-s means within the cycles' records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from gyrocal.analysis.thermal.warmup import (
    COVERAGE_K,
    Repeatability,
    WarmupFit,
    bin_means,
    fit_warmup,
    measured_time_to_band_s,
    turn_on_repeatability,
)
from gyrocal.metrology.metrics import (
    TURN_ON_REPEATABILITY,
    TURN_ON_TIME,
    WARMUP_AMPLITUDE,
    WARMUP_TAU,
    WARMUP_TIME_TO_BAND,
)
from gyrocal.reports.sections.headline import StatedUncertainty

#: bin of the warm-up fit (the record's white noise averages down in it)
BIN_S = 1.0


@dataclass(frozen=True)
class TurnOnRecord:
    step_id: str
    temp_c: float
    band_dph: float
    on_clock_s: float
    first_frame_after_s: float
    poll_s: float
    t_s: np.ndarray           # clock time of each sample
    bias_dph: np.ndarray      # output / nominal SF, deg/h


@dataclass(frozen=True)
class Warmup:
    """A power cycle's warm-up fit and the times to the band it gives."""

    fit: WarmupFit
    time_to_band_s: float
    u_time_to_band_s: float
    measured_time_to_band_s: float | None

    def to_json(self) -> dict[str, Any]:
        fit = self.fit
        return {
            "settled_bias_dph": fit.settled_dph, "u_settled_bias_dph": fit.u_settled_dph,
            "warmup_tau_s": fit.tau_s, "u_warmup_tau_s": fit.u_tau_s,
            "U_warmup_tau_s": COVERAGE_K * fit.u_tau_s,
            "warmup_amplitude_dph": fit.amplitude_dph,
            "u_warmup_amplitude_dph": fit.u_amplitude_dph,
            "U_warmup_amplitude_dph": COVERAGE_K * fit.u_amplitude_dph,
            "time_to_band_s": self.time_to_band_s, "u_time_to_band_s": self.u_time_to_band_s,
            "U_time_to_band_s": COVERAGE_K * self.u_time_to_band_s,
            "measured_time_to_band_s": self.measured_time_to_band_s}


@dataclass(frozen=True)
class TurnOnTest:
    """One power cycle: the time to first data, and the warm-up when it could be fitted."""

    step_id: str
    temp_c: float
    band_dph: float
    time_to_first_data_s: float
    u_time_to_first_data_s: float
    warmup: Warmup | None

    def to_json(self) -> dict[str, Any]:
        out = {"step_id": self.step_id, "temp_c": self.temp_c, "band_dph": self.band_dph,
               "time_to_first_data_s": self.time_to_first_data_s,
               "u_time_to_first_data_s": self.u_time_to_first_data_s,
               "U_time_to_first_data_s": COVERAGE_K * self.u_time_to_first_data_s}
        return out if self.warmup is None else out | self.warmup.to_json()


def _one(record: TurnOnRecord, notes: list[str]) -> TurnOnTest:
    since_on_s = record.t_s - record.on_clock_s
    test = TurnOnTest(record.step_id, record.temp_c, record.band_dph,
                      record.first_frame_after_s, record.poll_s / math.sqrt(12.0), None)
    try:
        fit = fit_warmup(since_on_s, record.bias_dph, BIN_S)
    except (ValueError, RuntimeError) as exc:
        notes.append(f"turn_on {record.step_id}: no warm-up fit ({exc})")
        return test
    t_band, u_band = fit.time_to_band_s(record.band_dph)
    measured = measured_time_to_band_s(since_on_s, record.bias_dph, fit.settled_dph,
                                       record.band_dph, BIN_S)
    if not (0.0 < fit.tau_s < 10.0 * float(since_on_s[-1])):
        notes.append(f"turn_on {record.step_id}: the fitted τ {fit.tau_s:.4g} s is not "
                     "determined by the record's length")
    return replace(test, warmup=Warmup(fit, t_band, u_band, measured))


@dataclass(frozen=True)
class TurnOnResults:
    """results.json ``turn_on``: one entry per power cycle; the headline numbers are the
    first cycle's (a procedure runs one turn_on per temperature)."""

    tests: tuple[TurnOnTest, ...]

    def to_json(self) -> dict[str, Any]:
        first = self.tests[0]
        warm = first.warmup
        return {"tests": [t.to_json() for t in self.tests], "k": COVERAGE_K,
                "band_dph": first.band_dph, "time_to_first_data_s": first.time_to_first_data_s,
                "warmup_tau_s": None if warm is None else warm.fit.tau_s,
                "warmup_amplitude_dph": None if warm is None else warm.fit.amplitude_dph,
                "time_to_band_s": None if warm is None else warm.time_to_band_s,
                "settled_bias_dph": None if warm is None else warm.fit.settled_dph}


def turn_on_section(records: list[TurnOnRecord], notes: list[str]) -> TurnOnResults | None:
    """results.json ``turn_on`` (None when the run has no turn_on step)."""
    if not records:
        return None
    return TurnOnResults(tuple(_one(r, notes) for r in records))


def turn_on_uncertainty(section: TurnOnResults | None) -> list[StatedUncertainty]:
    """The stated uncertainties of the turn_on headline numbers (the first power cycle's)."""
    if section is None:
        return []
    first = section.tests[0]
    out = [StatedUncertainty(TURN_ON_TIME, first.time_to_first_data_s,
                             first.u_time_to_first_data_s,
                             COVERAGE_K * first.u_time_to_first_data_s, COVERAGE_K, "s",
                             "rectangular over the first-frame poll interval")]
    warm = first.warmup
    if warm is None:
        return out
    fit = warm.fit
    return out + [
        StatedUncertainty(WARMUP_TAU, fit.tau_s, fit.u_tau_s, COVERAGE_K * fit.u_tau_s,
                          COVERAGE_K, "s", "type A of the least-squares warm-up fit (1-s bin means)"),
        StatedUncertainty(WARMUP_AMPLITUDE, fit.amplitude_dph, fit.u_amplitude_dph,
                          COVERAGE_K * fit.u_amplitude_dph, COVERAGE_K, "deg/h",
                          "type A of the least-squares warm-up fit"),
        StatedUncertainty(WARMUP_TIME_TO_BAND, warm.time_to_band_s, warm.u_time_to_band_s,
                          COVERAGE_K * warm.u_time_to_band_s, COVERAGE_K, "s",
                          "τ·ln(|A|/band), propagated from the fit's covariance")]


@dataclass(frozen=True)
class CycleRecord:
    step_id: str              # ``<test>.c<n>``
    temp_c: float
    t_s: np.ndarray
    bias_dph: np.ndarray


def _test_of(step_id: str) -> str:
    return step_id.rsplit(".c", 1)[0]


@dataclass(frozen=True)
class RepeatabilityTest:
    """One turn_on_repeatability test: its cycles' biases, their spread, the in-run spread."""

    test: str
    temp_c: float
    repeatability: Repeatability
    in_run_std_dph: float

    def to_json(self) -> dict[str, Any]:
        rep = self.repeatability
        return {"test": self.test, "temp_c": self.temp_c, "cycles": rep.n,
                "biases_dph": list(rep.biases_dph), "std_dph": rep.std_dph,
                "u_std_dph": rep.u_std_dph, "U_std_dph": COVERAGE_K * rep.u_std_dph,
                "in_run_std_dph": self.in_run_std_dph}


@dataclass(frozen=True)
class RepeatabilityResults:
    """results.json ``turn_on_repeatability``: one entry per test; the headline the first's."""

    tests: tuple[RepeatabilityTest, ...]

    def to_json(self) -> dict[str, Any]:
        first = self.tests[0]
        return {"tests": [t.to_json() for t in self.tests], "k": COVERAGE_K,
                "std_dph": first.repeatability.std_dph, "in_run_std_dph": first.in_run_std_dph}


def _group(cycles: list[CycleRecord], notes: list[str]) -> RepeatabilityTest | None:
    if len(cycles) < 2:
        notes.append(f"turn_on_repeatability {_test_of(cycles[0].step_id)}: one completed "
                     "cycle; the repeatability needs two")
        return None
    rep = turn_on_repeatability([float(np.mean(c.bias_dph)) for c in cycles])
    variances = [float(np.var(bin_means(c.t_s, c.bias_dph, BIN_S)[1], ddof=1)) for c in cycles]
    return RepeatabilityTest(_test_of(cycles[0].step_id), cycles[0].temp_c, rep,
                             math.sqrt(float(np.mean(variances))))


def repeatability_section(cycles: list[CycleRecord], notes: list[str]
                          ) -> RepeatabilityResults | None:
    """results.json ``turn_on_repeatability`` (None when no test has two cycles)."""
    groups: dict[str, list[CycleRecord]] = {}
    for cycle in cycles:
        groups.setdefault(_test_of(cycle.step_id), []).append(cycle)
    tests = [t for t in (_group(g, notes) for g in groups.values()) if t is not None]
    return RepeatabilityResults(tuple(tests)) if tests else None


def repeatability_uncertainty(section: RepeatabilityResults | None) -> list[StatedUncertainty]:
    if section is None:
        return []
    rep = section.tests[0].repeatability
    return [StatedUncertainty(TURN_ON_REPEATABILITY, rep.std_dph, rep.u_std_dph,
                              COVERAGE_K * rep.u_std_dph, COVERAGE_K, "deg/h",
                              "s/√(2(N−1)) of the standard deviation of N normal biases")]
