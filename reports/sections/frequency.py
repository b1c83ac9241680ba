"""The report's frequency-response section (IEEE Std 952 / 1431 "frequency response").

Each completed frequency step gives its logged samples: the gyro output and the
sinusoid the table turned (logged as the table rate, orchestrator/table_synthesis.py).
analysis/rate/frequency_response.py fits the sines; this module adds what the run itself
contributes to the phase and groups the result per temperature.

The logged sample times are the step's start on the run's clock plus the frame index
over the sample rate, so a frame is placed to within one sample period of when the unit
sampled it (the first frame after the flush may have been sampled up to a period before
or after the start). That offset shifts the phase by up to 360°·f/fs at frequency f and
leaves the gain alone: it enters each phase as a rectangular type B term of that
half-width. A real table's command latency (the sinusoid's start read from the clock
when the mode command is answered) is not in it; a rig's phase needs its own budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyrocal.analysis.rate.frequency_response import (
    COVERAGE_K,
    Bandwidth,
    ResponsePoint,
    bandwidth_3db,
    phase_at,
    response_point,
)
from gyrocal.metrology.metrics import BANDWIDTH, PHASE
from gyrocal.reports.sections.headline import StatedUncertainty

STANDARD_TEST = "frequency response (IEEE Std 952 / 1431)"


@dataclass(frozen=True)
class FrequencyDwell:
    """One frequency step's samples: times (s), gyro output, the reference table rate."""

    step_id: str
    setpoint_c: float
    freq_hz: float
    amplitude_dps: float
    phase_at_hz: float
    t_s: np.ndarray
    output: np.ndarray
    reference_dps: np.ndarray


def timing_half_width_deg(freq_hz: float, sample_rate_hz: float) -> float:
    """Phase half-width of a one-sample placement uncertainty (module docstring)."""
    return 360.0 * freq_hz / sample_rate_hz


def point(dwell: FrequencyDwell, nominal_sf: float, sample_rate_hz: float) -> ResponsePoint:
    """The fitted gain and phase, the phase's u with the timing term added."""
    fitted = response_point(dwell.t_s, dwell.output, dwell.reference_dps, dwell.freq_hz,
                            nominal_sf)
    timing_u = timing_half_width_deg(dwell.freq_hz, sample_rate_hz) / math.sqrt(3.0)
    return ResponsePoint(fitted.freq_hz, fitted.gain, fitted.u_gain, fitted.phase_deg,
                         math.hypot(fitted.u_phase_deg, timing_u))


@dataclass(frozen=True)
class FrequencyTest:
    """The response at one temperature: the points, the −3 dB crossing, the stated phase."""

    temp_c: float
    amplitude_dps: float
    sample_rate_hz: float
    points: tuple[ResponsePoint, ...]
    band: Bandwidth | None
    phase_at_hz: float
    phase: tuple[float, float] | None       # (phase_deg, u_phase_deg) at phase_at_hz

    @property
    def bandwidth_hz(self) -> float | None:
        return None if self.band is None else self.band.value_hz

    @property
    def phase_deg(self) -> float | None:
        return None if self.phase is None else self.phase[0]

    def to_json(self) -> dict[str, Any]:
        band, phase = self.band, self.phase
        return {
            "temp_c": self.temp_c, "standard_test": STANDARD_TEST,
            "amplitude_dps": self.amplitude_dps, "sample_rate_hz": self.sample_rate_hz,
            "points": [{"freq_hz": p.freq_hz, "gain": p.gain, "u_gain": p.u_gain,
                        "gain_db": p.gain_db, "u_gain_db": p.u_gain_db,
                        "phase_deg": p.phase_deg, "u_phase_deg": p.u_phase_deg}
                       for p in self.points],
            "bandwidth_hz": None if band is None else band.value_hz,
            "u_bandwidth_hz": None if band is None else band.u_hz,
            "U_bandwidth_hz": None if band is None else band.expanded_hz,
            "u_bandwidth_type_a_hz": None if band is None else band.u_type_a_hz,
            "bandwidth_interpolation_half_width_hz": None if band is None else band.half_width_b_hz,
            "phase_at_hz": self.phase_at_hz,
            "phase_deg": None if phase is None else phase[0],
            "u_phase_deg": None if phase is None else phase[1],
            "U_phase_deg": None if phase is None else COVERAGE_K * phase[1],
        }


@dataclass(frozen=True)
class FrequencyResults:
    """results.json ``frequency_response``: per temperature, the smallest bandwidth and the
    first temperature's phase."""

    tests: tuple[FrequencyTest, ...]

    @property
    def bandwidth_hz(self) -> float | None:
        values = [t.bandwidth_hz for t in self.tests]
        return None if not values or any(v is None for v in values) else min(values)

    @property
    def phase_deg(self) -> float | None:
        return self.tests[0].phase_deg if self.tests else None

    def to_json(self) -> dict[str, Any]:
        return {"tests": [t.to_json() for t in self.tests], "bandwidth_hz": self.bandwidth_hz,
                "phase_deg": self.phase_deg, "k": COVERAGE_K}


def frequency_section(dwells: list[FrequencyDwell], nominal_sf: float, sample_rate_hz: float,
                      notes: list[str]) -> FrequencyResults | None:
    """Per temperature: points, −3 dB bandwidth and the phase at the stated frequency."""
    if not dwells:
        return None
    groups: dict[float, list[FrequencyDwell]] = {}
    for dwell in dwells:
        groups.setdefault(dwell.setpoint_c, []).append(dwell)
    tests = []
    for temp, members in groups.items():
        points: list[ResponsePoint] = []
        for dwell in members:
            try:
                points.append(point(dwell, nominal_sf, sample_rate_hz))
            except ValueError as exc:
                notes.append(f"frequency response: {dwell.step_id}: {exc}")
        tests.append(_test(temp, members[0], points, sample_rate_hz, notes))
    return FrequencyResults(tuple(tests))


def _test(temp: float, first: FrequencyDwell, points: list[ResponsePoint],
          sample_rate_hz: float, notes: list[str]) -> FrequencyTest:
    band = bandwidth_3db(points)
    if band is None and points:
        notes.append(f"frequency response at {temp:g} °C: the gain never falls through −3 dB "
                     f"between {points[0].freq_hz:g} and {points[-1].freq_hz:g} Hz; no bandwidth")
    return FrequencyTest(temp, first.amplitude_dps, sample_rate_hz, tuple(points), band,
                         first.phase_at_hz, phase_at(points, first.phase_at_hz))


def frequency_uncertainty(section: FrequencyResults | None) -> list[StatedUncertainty]:
    """The stated uncertainties of the bandwidth and the phase (results.json ``uncertainty``)."""
    out: list[StatedUncertainty] = []
    if section is None:
        return out
    band = section.bandwidth_hz
    entry = next((t for t in section.tests if t.bandwidth_hz == band), None)
    if band is not None and entry is not None and entry.band is not None:
        out.append(StatedUncertainty(
            BANDWIDTH, band, entry.band.u_hz, entry.band.expanded_hz, COVERAGE_K, "Hz",
            "type A from the fitted gains at the two frequencies around −3 dB, "
            "combined with a rectangular term of the linear/log interpolation spread"))
    first = section.tests[0] if section.tests else None
    if first is not None and first.phase is not None:
        out.append(StatedUncertainty(
            PHASE, first.phase[0], first.phase[1], COVERAGE_K * first.phase[1], COVERAGE_K,
            "deg", "type A of the sine fits and a rectangular one-sample timing term, "
                   "interpolated linearly to the stated frequency"))
    return out
