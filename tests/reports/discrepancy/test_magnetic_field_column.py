"""A log carrying the coil's field (``field_t``) lets the workflow name magnetic_sensitivity.

Hidden truth typed here: 2000 deg/(h·T) with the coil stepping between +1 mT,
0 and -1 mT every 5 minutes (±2 deg/h steps, far above the nominal model's
0.01 deg/√h ARW binned over minutes). Without the column the effect is not
searched at all (its signature would be zero).
"""

from __future__ import annotations

import discrepancy_scenarios as scenarios
import numpy as np
import pytest

from gyrocal.analysis.discrepancy.signatures import searched_effects
from gyrocal.analysis.discrepancy.workflow import analyse
from gyrocal.analysis.measured_log import MeasuredLog
from gyrocal.models.gyro_model import EffectSpec
from gyrocal.models.gyro_sim import simulate
from gyrocal.models.indicated import ModelInputs

K_DPH_PER_T = 2000.0


def _field_t(t_s: np.ndarray) -> np.ndarray:
    cycle = np.array([1.0e-3, 0.0, -1.0e-3, 0.0])
    return cycle[(t_s // 300.0).astype(int) % 4]


@pytest.mark.timeout(120)
def test_the_field_column_names_the_magnetic_sensitivity_and_its_size():
    prof = scenarios.procedure_profile(3600.0, 5.0)
    truth = scenarios.true_base(scenarios.nominal_model()).with_effect(
        EffectSpec("magnetic_sensitivity", {"dph_per_t": K_DPH_PER_T}))
    field = _field_t(prof.t_s)
    samples = simulate(truth, prof.t_s, prof.table_rate_dps, prof.chamber_temp_c, seed=7,
                       field_t=field)
    log = MeasuredLog("simulated", samples.t_s, samples.table_rate_dps, samples.chamber_temp_c,
                      samples.gyro, field_t=field)
    result = analyse(scenarios.nominal_model(), log, seed=7, n_null=200, max_bins=1000)
    assert result.found and result.found[0].name == "magnetic_sensitivity"
    got = result.found[0].parameters["dph_per_t"]
    assert abs(got - K_DPH_PER_T) < 0.05 * K_DPH_PER_T, got


def test_without_the_field_column_the_effect_is_not_searched():
    prof = scenarios.procedure_profile(3600.0, 5.0)
    nominal = scenarios.nominal_model()
    assert "magnetic_sensitivity" not in searched_effects(nominal, prof.inputs)
    with_field = ModelInputs.of(prof.t_s, prof.table_rate_dps, prof.chamber_temp_c,
                                field_t=_field_t(prof.t_s))
    assert "magnetic_sensitivity" in searched_effects(nominal, with_field)


def test_a_csv_log_with_field_t_is_read_and_an_impossible_field_named(tmp_path):
    from gyrocal.analysis.measured_log import LogFormatError, read_measured_log

    good = tmp_path / "log.csv"
    good.write_text("t_s,table_rate_dps,chamber_temp_c,gyro,field_t\n"
                    "0.0,0.0,25.0,0.001,0.0005\n0.2,0.0,25.0,0.001,0.0\n0.4,0.0,25.0,0.001,-0.0005\n")
    log = read_measured_log(good)
    np.testing.assert_array_equal(log.field_t, [5e-4, 0.0, -5e-4])
    bad = tmp_path / "bad.csv"
    bad.write_text(good.read_text().replace("-0.0005", "250"))
    with pytest.raises(LogFormatError, match=r"field_t"):
        read_measured_log(bad)
