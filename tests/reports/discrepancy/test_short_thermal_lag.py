"""A thermal lag shorter than a few bins, on a slow-sampled staircase: is it named?

On a 3-hour log at 2 Hz analysed on 1000 bins a bin is 11 s wide, and the τ
grid that starts at three bins (33 s) cannot reach a clear lag of a quarter
minute. The table turning during the ramps makes such a lag visible through
the SF tempco (ω·sf_tempco·τ·dT/dt), so at 10σ it must be named, not lost to
an out-of-catalogue probe or to nothing.
"""

from __future__ import annotations

import functools
import math

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.signatures import SearchSpace, searched_effects, shape_grid
from gyrocal.models.indicated import ModelInputs

MAX_BINS = 1000
FS_HZ = 2.0
DURATION_S = 10800.0
#: soaks and ramps: 25 °C for 30 min, 1 °C/min to 45 °C, 30 min, 1.5 °C/min to 10 °C, then soaked
KNOTS_S = (0.0, 1800.0, 3000.0, 4800.0, 6200.0, DURATION_S)
KNOTS_C = (25.0, 25.0, 45.0, 45.0, 10.0, 10.0)
#: a rate ladder (deg/s, s), run in each soak and through each ramp
LADDER = ((0.0, 60.0), (2.0, 60.0), (-2.0, 60.0), (10.0, 60.0), (-10.0, 60.0),
          (30.0, 60.0), (-30.0, 60.0), (60.0, 60.0), (-60.0, 60.0))
LADDER_STARTS_S = (300.0, 2100.0, 3300.0, 5200.0, 7000.0)


@functools.lru_cache(maxsize=1)
def staircase() -> scenarios.Profile:
    t = np.arange(int(DURATION_S * FS_HZ)) / FS_HZ
    rate = np.zeros_like(t)
    for start in LADDER_STARTS_S:
        at = start
        for rate_dps, length_s in LADDER:
            rate[(t >= at) & (t < at + length_s)] = rate_dps
            at += length_s
    return scenarios.Profile(t, scenarios._slewed(rate, FS_HZ, 10.0), np.interp(t, KNOTS_S, KNOTS_C))


def test_thermal_lag_grid_reaches_below_the_bins():
    """A 1 Hz, 12-hour log on 1000 bins (43 s wide): lags of a few seconds are still tried."""
    space = SearchSpace(43200.0, 43.2, (0.0,), (), 1.0)
    taus = [g["tau_s"] for g in shape_grid("thermal_lag", space)]
    assert min(taus) <= 4.0
    assert min(taus) >= 2.0                      # never below two samples
    assert taus == sorted(taus)
    steps = np.diff(np.log(taus))
    assert steps.max() <= math.log(2.0) + 1e-9   # no hole the refinement cannot bridge


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", [310, 311])
def test_short_lag_on_a_slow_staircase_is_named(seed):
    prof = staircase()
    truth = scenarios.sized_effect("thermal_lag", 10.0, prof, max_bins=MAX_BINS)
    bin_width_s = math.ceil(len(prof.t_s) / MAX_BINS) / FS_HZ
    # the case this test is about: a 10σ lag shorter than three bins
    assert truth["tau_s"] < 3.0 * bin_width_s, truth
    result = scenarios.analyse_scenario(prof, [truth], seed, max_bins=MAX_BINS)
    assert result.found, f"nothing named; unexplained {result.unexplained}: {result.where}"
    first = result.found[0]
    assert first.name == "thermal_lag", (first.name, result.where)
    assert abs(math.log(first.parameters["tau_s"] / truth["tau_s"])) < math.log(2.0)
    assert not result.unexplained, result.where


def test_thermal_lag_not_scored_when_the_sensor_temperature_is_measured():
    """With sensor_temp_c the equation uses it, not the lagged chamber: no lag to search."""
    prof = staircase()
    model = scenarios.nominal_model()
    assert "thermal_lag" in searched_effects(model, prof.inputs)
    measured = ModelInputs.of(prof.t_s, prof.table_rate_dps, prof.chamber_temp_c,
                              sensor_temp_c=prof.chamber_temp_c - 0.5)
    names = searched_effects(model, measured)
    assert "thermal_lag" not in names
    assert "temp_rate_bias" in names
