"""A spectral line present in part of the record only is unexplained and described (issue 29).

The catalogue's periodic_interference looks for a constant line over the whole
record; a line only at high |rate| (amplitude ∝ |ω|) or only while the chamber
cools is diluted there. On the third held-out set a line near 0.37·fs with
amplitude ∝ |ω| was neither named nor unexplained in 5 of 5 runs. banded_line.py
looks at the final residual's periodogram over parts of the record. Our own
cases (``banded_line_cases``): a tone at 0.29·fs ∝ |ω| on the Q2-like profile,
one at 0.17·fs only while cooling on P1 (1 h, 5 Hz), sized ‖s‖ = 10σ of the white noise.

Measured (``benchmarks/validate_banded_line.py``, the test on the base refit):
see banded_line.py's docstring and docs/discrepancy-validation.md.
"""

from __future__ import annotations

import functools

import banded_line_cases as cases
import discrepancy_scenarios as scenarios
import pytest

from gyrocal.analysis.discrepancy.banded_line import banded_scan, high_passed, record_parts
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.noise_model import NoiseModel

MAX_BINS = 1000


@functools.lru_cache(maxsize=1)
def q2() -> scenarios.Profile:
    """Q2-like: 45 min at 50 Hz, 25 → 60 → 5 → 25 °C at 5 °C/min, ±0.2…300 deg/s, 50 deg/s²."""
    return scenarios.procedure_profile(2700.0, 50.0, setpoints_c=(25.0, 60.0, 5.0, 25.0),
                                       ramps_c_per_min=(5.0, 5.0, 5.0), rates_dps=(0.2, 3.0, 20.0, 300.0),
                                       dwell_s=15.0, static_s=60.0, slow_rate_dps=6.0, accel_dps2=50.0)


@functools.lru_cache(maxsize=1)
def p1() -> scenarios.Profile:
    """1 hour at 5 Hz, soaks at 25/40/10/25 °C, the table at 10 deg/s² (validate_discrepancy's P1)."""
    return scenarios.procedure_profile(3600.0, 5.0, accel_dps2=10.0)


def scan_alone(prof: scenarios.Profile, seed: int, extra=None, hidden=None):
    """The test alone on the base refit of a simulated log (no effect search)."""
    log = scenarios.as_measured_log(scenarios.simulate_log(prof, hidden or [], seed, extra_dph=extra))
    model = scenarios.nominal_model()
    ctx = Context(model, log, seed, 300, MAX_BINS)
    ctx.use_noise(NoiseModel.of_model(model))
    after = ctx.fit(model)
    return banded_scan(high_passed(ctx.resid_full(after), ctx.bins.samples_per_bin), ctx.fs_hz, ctx.noise,
                       0.5 / ctx.bins.width_s, record_parts(log.table_rate_dps, log.chamber_temp_c, ctx.fs_hz))


def _claims(result) -> list[tuple[str, float]]:
    return [(f.name, round(f.probability, 3)) for f in result.found]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("seed", [9301, 9302])
def test_a_line_following_rate_is_unexplained_and_described(seed):
    extra = cases.rate_line(q2(), 0.29, 10.0)
    result = scenarios.analyse_scenario(q2(), [], seed, max_bins=MAX_BINS, extra_dph=extra)
    assert result.unexplained
    assert result.where.startswith("a spectral line at 14.5 Hz"), result.where
    assert "|rate|" in result.where.split(";")[0], result.where
    assert all(p < 0.8 for _, p in _claims(result)), _claims(result)


@pytest.mark.timeout(120)
def test_a_line_only_while_cooling_is_unexplained_and_described():
    extra = cases.cooling_line(p1(), 0.85, 10.0)
    result = scenarios.analyse_scenario(p1(), [], 9303, max_bins=MAX_BINS, extra_dph=extra)
    assert result.unexplained
    first = result.where.split(";")[0]
    assert first.startswith("a spectral line at ") and "only while cooling" in first, result.where
    assert float(first.split()[4]) == pytest.approx(0.85, abs=2.0 / 3600.0), result.where
    assert all(p < 0.8 for _, p in _claims(result)), _claims(result)


@pytest.mark.timeout(120)
def test_a_strong_part_time_line_named_periodic_interference_loses_the_claim():
    """25σ while cooling on Q2: the whole-record spectrum sees enough of it to name a constant line."""
    extra = cases.cooling_line(q2(), 8.5, 25.0)
    result = scenarios.analyse_scenario(q2(), [], 9304, max_bins=MAX_BINS, extra_dph=extra)
    assert result.unexplained
    assert "a spectral line at 8.5 Hz only while cooling" in result.where, result.where
    assert all(p < 0.8 for _, p in _claims(result)), _claims(result)


@pytest.mark.timeout(120)
def test_a_constant_line_stays_periodic_interference():
    """The catalogue's shape at 10σ: named first, and the part test does not call it part-only."""
    spec = scenarios.sized_effect("periodic_interference", 10.0, q2(), max_bins=MAX_BINS)
    result = scenarios.analyse_scenario(q2(), [spec], 9305, max_bins=MAX_BINS)
    assert result.found and result.found[0].name == "periodic_interference", _claims(result)
    assert result.found[0].probability >= 0.99
    assert "a spectral line at" not in result.where, result.where
    line = scan_alone(q2(), 9306, cases.constant_line(q2(), 11.5, 10.0))
    assert line.present and not line.part_only, line


@pytest.mark.parametrize("seed", range(9310, 9316))
def test_effect_free_records_do_not_fire(seed):
    """Fixed seeds of the controls (the benchmark's rate: see the module docstring)."""
    for prof in (q2(), p1()):
        line = scan_alone(prof, seed)
        assert line is not None and not line.present, line
        assert line.n_parts >= 12       # |rate| bands, weighted, at rest, temperature, heating/cooling, quarters
