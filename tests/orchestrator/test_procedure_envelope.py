"""The safe envelope on its own: each bound reads the right limit of the procedure and the station.

The limits are read through typed accessors (``envelope.Bound``), not key strings; these
tests put a distinct number in every limit so a bound that read a neighbouring field
(min for max, rate for acceleration, procedure for station) would name the wrong number.
"""

from pathlib import Path

import pytest

from gyrocal.inputs import YamlDocument
from gyrocal.orchestrator.procedure import ChamberSafety, Safety, TableSafety
from gyrocal.orchestrator.procedure.envelope import (
    MAX_ACCEL,
    MAX_RAMP,
    MAX_RATE,
    MAX_TEMP,
    MIN_TEMP,
    Envelope,
)
from gyrocal.orchestrator.station import load_station
from gyrocal.schema import Context

pytestmark = pytest.mark.timeout(30)

REPO = Path(__file__).resolve().parents[2]
# stations/sim.yaml: chamber -70..150 °C at 5 °C/min, table 500 deg/s at 100 deg/s²
STATION = load_station(REPO / "stations" / "sim.yaml")
SAFETY = Safety(ChamberSafety(-40.0, 80.0, 2.0), TableSafety(400.0, 50.0))


def _envelope(safety=SAFETY, station=STATION) -> Envelope:
    document = YamlDocument(file="p.yaml", path=Path("p.yaml").resolve(), data={})
    return Envelope(Context(document), safety, station)


@pytest.mark.parametrize(("bound", "procedure_value", "station_value"), [
    (MIN_TEMP, -40.0, -70.0), (MAX_TEMP, 80.0, 150.0), (MAX_RAMP, 2.0, 5.0),
    (MAX_RATE, 400.0, 500.0), (MAX_ACCEL, 50.0, 100.0),
])
def test_each_bound_reads_its_own_field_of_both_files(bound, procedure_value, station_value):
    procedure, station = _envelope().limits(bound)
    assert (procedure.value, procedure.where) == (
        procedure_value, f"procedure safety.{bound.group}.{bound.key}")
    assert (station.value, station.where) == (
        station_value, f"station {STATION.file}: {bound.group}.limits.{bound.key}")


def test_the_tightest_broken_limit_is_named():
    envelope = _envelope()
    envelope.check_rate(("r",), 450.0)        # beyond the procedure's 400 only
    envelope.check_rate(("r",), 600.0)        # beyond both: the procedure's is tighter
    envelope.check_setpoint(("t",), -50.0)    # below the procedure's -40 only
    envelope.check_accel(("a",), 0.001)       # below the plausible floor
    messages = [p.message for p in envelope.ctx.problems]
    assert messages == [
        "450 deg/s exceeds the table limit 400 deg/s (procedure safety.table.max_rate_dps)",
        "600 deg/s exceeds the table limit 400 deg/s (procedure safety.table.max_rate_dps)",
        "-50 °C is below the chamber limit -40 °C (procedure safety.chamber.min_temp_c)",
        "0.001 deg/s² is below the plausible minimum 0.01 deg/s² (a gentler acceleration is "
        "a typo)",
    ]


def test_without_a_procedure_safety_block_the_station_limits_still_hold():
    envelope = _envelope(safety=None)
    envelope.check_ramp(("ramp",), 6.0)
    envelope.check_ramp(("ramp",), 4.0)
    assert [p.message for p in envelope.ctx.problems] == [
        f"6 °C/min exceeds the chamber limit 5 °C/min (station {STATION.file}: "
        "chamber.limits.max_ramp_c_per_min)"]


def test_a_sinusoid_is_refused_at_its_first_frequency_whose_peak_acceleration_is_too_high():
    envelope = _envelope()
    # 2π·f·10 deg/s: 0.5 Hz peaks at 31.4, 1 Hz at 62.8 (> 50), 2 Hz at 126 deg/s²
    envelope.check_peak_accel(("f",), (0.5, 1.0, 2.0), 10.0)
    [problem] = envelope.ctx.problems
    assert problem.path == "f[1]"
    assert problem.message.startswith("1 Hz at 10 deg/s peaks at 62.8")
    assert problem.message.endswith("the table limit 50 deg/s² (procedure safety.table.max_accel_dps2)")


def test_procedure_limits_outside_the_station_are_named_against_the_station_file():
    envelope = _envelope(safety=None)
    wide = (ChamberSafety(-80.0, 80.0, 2.0), TableSafety(400.0, 150.0))
    envelope.check_within_station(("safety", "chamber"), wide[0], ("safety", "table"), wide[1])
    assert [(p.path, p.message) for p in envelope.ctx.problems] == [
        ("safety.chamber.min_temp_c", f"-80 °C is below the station chamber limit -70 °C "
         f"({STATION.file}: chamber.limits.min_temp_c)"),
        ("safety.table.max_accel_dps2", f"150 deg/s² exceeds the station table limit "
         f"100 deg/s² ({STATION.file}: table.limits.max_accel_dps2)"),
    ]
