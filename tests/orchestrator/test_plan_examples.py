"""The shipped procedures validate against the sim station and expand to the expected plans."""

import math
from pathlib import Path

import pytest
import yaml

from gyrocal.orchestrator.plan import dwell_for_rate, expand_plan, format_plan
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.problems import ProcedureError

pytestmark = pytest.mark.timeout(30)

REPO = Path(__file__).resolve().parents[2]
PROCEDURES = sorted((REPO / "procedures").glob("*.yaml"))
SIM = REPO / "stations" / "sim.yaml"
#: procedures whose tests need what sim.yaml lacks (a coil on a supply, a horizontal table,
#: a supply that switches the unit for turn_on):
#: their own station
OWN_STATION = {"magnetic-sensitivity.yaml", "tilt-linearity.yaml", "acceptance-series.yaml"}


def plan_of(name):
    return expand_plan(load_procedure(REPO / "procedures" / name, SIM))


def test_the_four_example_procedures_are_shipped():
    assert {p.name for p in PROCEDURES} >= {
        "fog-overnight-sf-temperature.yaml", "imu-calibration-5-temps.yaml", "smoke.yaml",
        "rlg-quantization-check.yaml"}


@pytest.mark.parametrize("path", PROCEDURES, ids=lambda p: p.name)
def test_every_example_validates_and_expands_with_unique_stable_ids(path):
    procedure = load_procedure(path, None if path.name in OWN_STATION else SIM)
    plan = expand_plan(procedure)
    ids = [s.step_id for s in plan.steps]
    assert len(ids) == len(set(ids))
    assert ids == [s.step_id for s in expand_plan(load_procedure(path)).steps]   # stable, same station key
    # every temperature step starts with a ramp and a soak to its setpoint
    for index, step in enumerate(procedure.sequence):
        own = [s for s in plan.steps if s.temp_index == index]
        assert [s.kind for s in own[:2]] == ["ramp", "soak"]
        assert {s.setpoint_c for s in own} == {step.setpoint_c}
        # every step carries its temperature's soak criterion, so a resumed run can re-soak
        assert {(s.tolerance_c, s.hold_s, s.max_wait_s) for s in own} == {
            (step.soak.tolerance_c, step.soak.hold_s, step.soak.max_wait_s)}
    # the ETA is the sum of the step estimates, and starts chain up
    assert plan.total_s == pytest.approx(sum(s.expected_s for s in plan.steps))
    for before, after in zip(plan.steps, plan.steps[1:], strict=False):
        assert after.start_s == pytest.approx(before.start_s + before.expected_s)
    text = format_plan(plan)
    assert plan.steps[-1].step_id in text and "ETA" in text


def test_overnight_fog_procedure_shape():
    plan = plan_of("fog-overnight-sf-temperature.yaml")
    raw = yaml.safe_load((REPO / "procedures" / "fog-overnight-sf-temperature.yaml").read_text())
    setpoints = [s["setpoint_c"] for s in raw["sequence"]]
    assert setpoints == [-40.0, -20.0, 0.0, 25.0, 50.0, 75.0]
    assert plan.total_s >= 16 * 3600
    dwells = [s for s in plan.steps if s.kind == "dwell"]
    # ± pairs at every rate up to the table limit, at every temperature
    assert max(abs(s.rate_dps) for s in dwells) == 500.0
    for temp_index in range(6):
        rates = [s.rate_dps for s in dwells if s.temp_index == temp_index]
        assert sorted(rates) == sorted([-r for r in rates])
        assert f"T{temp_index + 1:02d}.sf.+500dps" in {s.step_id for s in dwells}
    # the paper dwells 3-5 min per rate and direction; whole revolutions only
    assert all(180.0 <= s.duration_s <= 300.0 for s in dwells)
    assert all(s.revolutions == int(s.revolutions) and s.revolutions >= 1 for s in dwells)
    allan = [s for s in plan.steps if s.kind == "allan"]
    assert len(allan) == 1 and allan[0].setpoint_c == 25.0 and allan[0].duration_s >= 3 * 3600


def test_overnight_fog_eta_from_first_principles():
    """Recompute the ETA from the YAML numbers alone (independent of the expander)."""
    raw = yaml.safe_load((REPO / "procedures" / "fog-overnight-sf-temperature.yaml").read_text())
    d = raw["defaults"]
    assert (d["ramp_c_per_min"], d["dwell"], d["settle"], d["accel_dps2"]) == (1.0, "3 min", "20 s", 20.0)
    rates = raw["templates"]["sweep"]["rates_dps"]
    temps = [s["setpoint_c"] for s in raw["sequence"]]
    ramp_s = sum(abs(b - a) for a, b in zip([22.0, *temps[:-1]], temps, strict=True)) * 60.0
    soak_s = 6 * 45 * 60.0
    static_s = 6 * (20 * 60.0 + 20.0)                # hold + settle
    allan_s = 3 * 3600.0 + 20.0
    sweep_s = 0.0
    for r in rates:
        dwell = math.ceil(max(180.0 * r / 360.0, 1) - 1e-9) * 360.0 / r
        sweep_s += 2 * (dwell + 20.0)
    # table moves at 20 deg/s² per temperature: 0→+r1, +r→-r, -r→+r_next, ..., -rmax→0,
    # which adds up to 4·Σr; the very last stop belongs to the return to the safe state
    accel_s = 6 * 4 * sum(rates) / 20.0 - rates[-1] / 20.0
    expected = ramp_s + soak_s + static_s + allan_s + 6 * sweep_s + accel_s
    assert plan_of("fog-overnight-sf-temperature.yaml").total_s == pytest.approx(expected, rel=1e-9)


def test_imu_calibration_temperatures_and_whole_turns():
    procedure = load_procedure(REPO / "procedures" / "imu-calibration-5-temps.yaml", SIM)
    assert [s.setpoint_c for s in procedure.sequence] == [-10.0, 5.0, 20.0, 30.0, 40.0]
    plan = expand_plan(procedure)
    dwells = [s for s in plan.steps if s.kind == "dwell"]
    assert len(dwells) == 5 * 5 * 2
    for step in dwells:
        # "rotation above 360° at the speed point": whole turns, at least two
        assert step.revolutions >= 2 and step.revolutions == int(step.revolutions)
        assert step.duration_s * abs(step.rate_dps) / 360.0 == pytest.approx(step.revolutions)
        assert step.duration_s >= 60.0
    statics = [s for s in plan.steps if s.kind == "static"]
    assert len(statics) == 5 and {s.label for s in statics} == {"one position"}


def test_rlg_rates_spread_the_fractional_phase_advance_over_a_full_cycle():
    plan = plan_of("rlg-quantization-check.yaml")
    rates = sorted({abs(s.rate_dps) for s in plan.steps if s.kind == "dwell"})
    assert len(rates) >= 20
    pulse_deg = 2.0 / 3600.0          # q = 2 arcsec, as the procedure's comment assumes
    readout_s = 1.0 / 2000.0
    phases = sorted(math.modf(r * readout_s / pulse_deg)[0] for r in rates)
    gaps = [b - a for a, b in zip(phases, phases[1:], strict=False)] + [1.0 - phases[-1] + phases[0]]
    assert max(gaps) < 0.1            # no part of [0, 1) left unvisited
    # static holds before and after the sweep, and an Allan hold for Q
    kinds = [s.kind for s in plan.steps if s.kind != "dwell"]
    assert kinds == ["ramp", "soak", "static", "static", "allan"]
    assert {"T01.static1", "T01.static2"} <= {s.step_id for s in plan.steps}


def test_smoke_is_a_few_minutes_and_its_eta_is_recomputed_by_hand():
    plan = plan_of("smoke.yaml")
    # ramps 22→23→27 °C at 5 °C/min; soaks 30 s; statics 2 s settle + 30 s;
    # per temperature 3 rates × 2 directions × (2 s settle + 10 s dwell);
    # table moves at 100 deg/s² per temperature: 0→10, 10→-10, -10→50, 50→-50, -50→100,
    # 100→-100 (5.4 s), then -100→0 before the second ramp (1 s); the last stop is not in the plan
    moves_s = 2 * (10 + 20 + 60 + 100 + 150 + 200) / 100.0 + 1.0
    expected = (1 + 4) / 5 * 60 + 2 * 30 + 2 * 32 + 2 * 6 * 12 + moves_s
    assert plan.total_s == pytest.approx(expected)
    assert 2 * 60 < plan.total_s < 10 * 60
    assert {s.setpoint_c for s in plan.steps} == {23.0, 27.0}


def test_overnight_procedure_does_not_fit_a_400_dps_table(tmp_path):
    """A table that stops at 400 deg/s: the 500 deg/s sweep must be refused up front."""
    lab = tmp_path / "lab-400.yaml"
    lab.write_text((REPO / "stations" / "lab-example.yaml").read_text().replace(
        "max_rate_dps: 500.0", "max_rate_dps: 400.0"))
    with pytest.raises(ProcedureError) as error:
        load_procedure(REPO / "procedures" / "fog-overnight-sf-temperature.yaml", lab)
    text = str(error.value)
    assert "safety.table.max_rate_dps: 500 deg/s exceeds the station table limit 400 deg/s" in text
    assert "rates_dps[9]: 500 deg/s exceeds the table limit 400 deg/s (station " in text


def test_dwell_for_rate_rounds_up_to_whole_revolutions():
    from gyrocal.orchestrator.procedure import SweepTest

    test = SweepTest((7.0,), None, "both", 60.0, 0.0, 10.0, 2, 1, None)
    dwell_s, turns = dwell_for_rate(test, 7.0)        # 60 s at 7 deg/s = 1.17 turns → 2 turns
    assert turns == 2.0 and dwell_s == pytest.approx(2 * 360.0 / 7.0)
    dwell_s, turns = dwell_for_rate(test, 30.0)       # 60 s = 5 turns exactly → kept
    assert turns == 5.0 and dwell_s == pytest.approx(60.0)


def test_resume_helpers():
    plan = plan_of("smoke.yaml")
    step = plan.steps[5]
    assert plan.index_of(step.step_id) == 5
    assert plan.remaining_s(step.step_id) == pytest.approx(plan.total_s - step.start_s)
    with pytest.raises(KeyError, match="no step 'T99.ramp'"):
        plan.index_of("T99.ramp")
