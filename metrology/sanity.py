"""Physical sense before any verdict: a run whose numbers are impossible is INVALID, never PASS.

A scale factor of 1e-6 against a nominal 1.0 is not a failed gyro, it is a
failed measurement (stale frames, a table that never turned, a units mix-up),
and no acceptance limit should be judged on it. So before acceptance the
report checks what physics demands of any gyro calibration:

* each scale factor lies within ``sf_tolerance_pct`` (procedure
  ``data_quality.sf_tolerance_pct``, default 5 %) of the unit's nominal one;
* nonlinearity and the scale-factor instability are finite and non-negative;
* every dwell's mean output has the sign of its commanded rate (× the nominal
  scale factor's sign) wherever the rate is large enough (≥ 1 deg/s) that no
  bias could flip it;
* every bias is finite;
* every dwell at ≥ 1 deg/s is steady: no tenth of it strays from the rest by
  more than its noise allows (8 standard errors) plus
  ``DRIFT_FLOOR_PPM`` of its mean output or ``DRIFT_FLOOR_DPH`` (× the
  nominal scale factor), whichever is larger — room for the slow physics of
  a real unit (bias instability, once-per-revolution terms), none for
  samples taken while the table was not at the dwell's rate (issue 28).

A failed check makes the verdict INVALID (exit 1, a red banner in the report
naming the check).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gyrocal.metrology.decision import Judged, OverallVerdict, overall_verdict
from gyrocal.metrology.metrics import (
    NONLINEARITY_MAX,
    NONLINEARITY_RMS,
    SF_INSTABILITY,
    metric_value,
)

DEFAULT_SF_TOLERANCE_PCT = 5.0
SIGN_CHECK_MIN_RATE_DPS = 1.0
DRIFT_FLOOR_PPM = 100.0     # of the dwell's mean output
DRIFT_FLOOR_DPH = 2.0       # deg/h, times the nominal scale factor
#: the catalogue's spreads this module checks are finite and non-negative
_SPREADS = (NONLINEARITY_RMS, NONLINEARITY_MAX, SF_INSTABILITY)


@dataclass(frozen=True)
class SanityCheck:
    name: str
    ok: bool
    detail: str


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def check_physics(results: dict[str, Any], sf_tolerance_pct: float | None = None
                  ) -> list[SanityCheck]:
    """The checks above, on a results dict (results.json before its verdict)."""
    tolerance = DEFAULT_SF_TOLERANCE_PCT if sf_tolerance_pct is None else float(sf_tolerance_pct)
    nominal = float((results.get("unit_under_test") or {}).get("nominal_scale_factor") or 1.0)
    checks = []
    bad_sf = [f"{e.get('temp_c')} °C: {e.get('sf')!r}" for e in results.get("scale_factor") or []
              if not _finite(e.get("sf")) or abs(e["sf"] / nominal - 1.0) * 100 > tolerance]
    checks.append(SanityCheck(
        "scale factor near nominal", not bad_sf,
        f"within ±{tolerance:g} % of the nominal {nominal:g}" if not bad_sf else
        f"outside ±{tolerance:g} % of the nominal {nominal:g}: {'; '.join(bad_sf)}"))
    negative = [f"{metric.key} = {value!r}" for metric in _SPREADS
                if (value := metric_value(results, metric)) is not None
                and not (_finite(value) and value >= 0)]
    checks.append(SanityCheck("non-negative spreads", not negative,
                              "finite and ≥ 0" if not negative else ", ".join(negative)))
    flipped = [f"{s['step_id']} ({s['rate_dps']:+g} deg/s) mean {s['output_mean']!r}"
               for s in results.get("steps") or []
               if s.get("kind") == "dwell" and abs(s.get("rate_dps") or 0) >= SIGN_CHECK_MIN_RATE_DPS
               and not (_finite(s.get("output_mean"))
                        and math.copysign(1, s["output_mean"]) == math.copysign(1, s["rate_dps"] * nominal))]
    checks.append(SanityCheck("dwell signs follow the table", not flipped,
                              "every dwell's mean has its rate's sign" if not flipped else
                              "; ".join(flipped[:5])))
    checks.append(_steady_dwells(results.get("steps") or [], nominal))
    bad_bias = [f"{b.get('temp_c')} °C: {b.get('bias_dph')!r}" for b in results.get("bias") or []
                if not _finite(b.get("bias_dph"))]
    checks.append(SanityCheck("bias finite", not bad_bias,
                              "every bias is a finite number" if not bad_bias else "; ".join(bad_bias)))
    if results.get("rate_limits"):
        checks.append(_rate_walk_line(results["rate_limits"], nominal, tolerance))
    if results.get("frequency_response"):
        checks.append(_low_frequency_follows(results["frequency_response"], tolerance))
    return checks


def _low_frequency_follows(section: dict[str, Any], tolerance: float) -> SanityCheck:
    """At the lowest frequency swept the output must follow the table: a gain far from 1 or a
    phase beyond ±90° (a swapped axis, a wrong SF, a table that did not move) makes the
    bandwidth meaningless."""
    bad = []
    for t in section.get("tests") or []:
        low = (t.get("points") or [None])[0]
        if low is None:
            continue
        gain, phase = low.get("gain"), low.get("phase_deg")
        if not (_finite(gain) and _finite(phase)) or abs(phase) >= 90.0 or \
                abs(gain - 1.0) * 100 > max(tolerance, 30.0):
            bad.append(f"{t.get('temp_c')} °C at {low.get('freq_hz')} Hz: gain {gain!r}, "
                       f"phase {phase!r}°")
    return SanityCheck("frequency response follows the table at its lowest frequency", not bad,
                       "gain near 1 and phase within ±90°" if not bad else "; ".join(bad))


def _rate_walk_line(section: dict[str, Any], nominal: float, tolerance: float) -> SanityCheck:
    """The rate-limit walk's line through its lowest rates must have the unit's scale factor:
    limits read off a line with the wrong sign or size (a swapped axis) mean nothing."""
    bad = [f"{t.get('temp_c')} °C {t.get('direction')}: SF {t.get('fit_sf'):.6g}"
           for t in section.get("tests") or []
           if not _finite(t.get("fit_sf")) or abs(t["fit_sf"] / nominal - 1.0) * 100 > tolerance]
    return SanityCheck("rate-limit walk follows the nominal SF", not bad,
                       f"its line is within ±{tolerance:g} % of the nominal {nominal:g}" if not bad
                       else "; ".join(bad))


def _steady_dwells(steps: list[dict[str, Any]], nominal: float) -> SanityCheck:
    """No part of a rate dwell far from the rest (``segment_drift`` in analysis/rate/dwell.py)."""
    unsteady = []
    for s in steps:
        drift = s.get("drift")
        if s.get("kind") != "dwell" or not drift or abs(s.get("rate_dps") or 0) < SIGN_CHECK_MIN_RATE_DPS:
            continue
        mean = abs(s.get("output_mean") or 0.0)
        floor = max(DRIFT_FLOOR_PPM * 1e-6 * mean, DRIFT_FLOOR_DPH / 3600.0 * abs(nominal))
        if not (_finite(drift.get("deviation")) and drift["deviation"] <= drift["noise_limit"] + floor):
            unsteady.append(
                f"{s['step_id']}: part {drift['segment'] + 1} of {drift['segments']} is "
                f"{drift['deviation'] / max(mean, 1e-300) * 1e6:.0f} ppm of the mean from the rest "
                f"(noise and drift allow {(drift['noise_limit'] + floor) / max(mean, 1e-300) * 1e6:.0f})")
    return SanityCheck("dwells steady", not unsteady,
                       "no part of a dwell strays from the rest" if not unsteady else
                       "; ".join(unsteady[:5]))


def verdict(checks: list[SanityCheck], acceptance: list[Judged]) -> OverallVerdict:
    """INVALID before FAIL before PASS; with the failed checks named (decision.py decides)."""
    return overall_verdict(checks, acceptance, [])
