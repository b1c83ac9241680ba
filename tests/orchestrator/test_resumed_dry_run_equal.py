"""A seeded dry run killed and resumed equals the uninterrupted one (issues 30 and 28).

What "equal" means (``engine.Rehearsal``): for every step, the attempt that
counts in the resumed run has the uninterrupted run's counted samples, value
for value in every column (time stamps, chamber and table context, gyro
output, sensor temperature, status); results.json holds the same numbers. Only
what records the interruption may differ: the run identity, wall times, the
loopback addresses, the attempt's number (a step cut mid-way is run again as
a new attempt, its cut attempt's chunks left as they are) and the journal's own
account (its events, event and chunk counts, the hash over every chunk).

Each run is killed by SIGKILL at one journal boundary (``GYROCAL_CRASH_AT``):
mid-step (a dwell's chunk written, the step not yet complete), between two
steps (the last dwell at 23 °C complete, the ramp to 27 °C not begun), and
between ``run_completed`` and ``run_closed``; then ``gyrocal resume``, which
takes the seed the run started with. (Every other boundary of a shorter run:
test_crash_every_boundary.py.)
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gyrocal.cli import main
from gyrocal.record.crash import CRASH_AT_ENV
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.samples import read_chunks
from tests.support.dry_run_compare import without
from tests.support.fork_server import ForkServer

#: results.json keys that name the run, a wall time, a loopback address, or count the
#: history (the journal block: its events, chunks and the hash over every chunk)
RESULTS_FREE = {"run_id", "started_at", "steps_started_at", "steps_done_at", "ended_at",
                "report_built_at", "address", "journal"}


def run_args(procedure: Path, out: Path) -> list[str]:
    return ["run", str(procedure), "--sim", "--seed", "11", "--out", str(out),
            "--allow-outside-paths"]


def counted_samples(run: Path) -> dict[str, tuple[int, dict[str, np.ndarray]]]:
    """step_id → (attempt, decoded columns of its counted attempt's chunks)."""
    folder = RunFolder(run)
    out = {}
    for event in folder.journal_events():
        if event.get("event") == "step_completed" and event.get("chunks"):
            out[event["step_id"]] = (event["attempt"], dict(read_chunks(folder.path, event["chunks"])))
    return out


def kill_points(events: list[dict[str, Any]]) -> dict[str, str]:
    """The boundaries of the reference run's journal this test kills at."""
    def seq(event: str, step_id: str | None = None) -> int:
        return next(e["seq"] for e in events
                    if e["event"] == event and (step_id is None or e.get("step_id") == step_id))

    return {
        "mid-step": f"before:{seq('step_completed', 'T01.sf.+20dps')}",
        "between-steps": f"after:{seq('step_completed', 'T01.sf.-20dps')}",
        "after-run-completed": f"after:{seq('run_completed')}",
    }


@pytest.mark.timeout(240)
def test_a_killed_and_resumed_dry_run_equals_the_uninterrupted_one(h, tmp_path, capsys):
    procedure = h.write_procedure(tmp_path)
    reference = tmp_path / "reference"
    assert main(run_args(procedure, reference)) in (0, 1)
    expected = counted_samples(reference)
    assert set(expected) == {"T01.static", "T01.sf.+20dps", "T01.sf.-20dps",
                             "T02.sf.+20dps", "T02.sf.-20dps"}
    expected_results = json.loads((reference / "report" / "results.json").read_text())
    # the state a resumed run restores is journaled where each step completed
    assert all("sim_state" in e for e in h.events(reference) if e["event"] == "step_completed")
    points = kill_points(h.events(reference))
    with ForkServer(h.REPO_ROOT) as server:
        for name, point in points.items():
            out = tmp_path / name
            status = server.run(run_args(procedure, out), {CRASH_AT_ENV: point},
                                tmp_path / f"{name}.err")
            assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (name, status)
            capsys.readouterr()
            assert main(["resume", str(out)]) in (0, 1), (name, capsys.readouterr())
            _assert_equal_run(h, out, name, expected, expected_results)


def _assert_equal_run(h, out: Path, name: str, expected, expected_results,
                      plan: list[str] | None = None, cut_step: str = "T01.sf.+20dps") -> None:
    events = h.events(out)
    assert h.completed_ids(out) == (list(h.SMALL_PLAN) if plan is None else plan), name
    got = counted_samples(out)
    assert set(got) == set(expected), name
    for step_id, (attempt, columns) in expected.items():
        got_attempt, got_columns = got[step_id]
        assert list(got_columns) == list(columns), (name, step_id)
        for column, values in columns.items():
            other = got_columns[column]
            assert values.dtype == other.dtype and values.tobytes() == other.tobytes(), (
                name, step_id, column)
        if name == "mid-step" and step_id == cut_step:
            # cut mid-way: run again as a new attempt, with the cut attempt's draws
            assert (attempt, got_attempt) == (1, 2), name
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["run"]["run_id"] != expected_results["run"]["run_id"]
    assert without(results, RESULTS_FREE) == without(expected_results, RESULTS_FREE), name
    kinds = [e["event"] for e in events]
    if name == "after-run-completed":
        assert "resumed" not in kinds and kinds[-1] == "run_closed", name
    else:       # the resumed session went on from the state the killed one had journaled
        restored = [e for e in events if e["event"] == "sim_state_restored"]
        assert len(restored) == 1 and "resumed" in kinds, name
        source = next(e for e in events if e["seq"] == restored[0]["from_seq"])
        # a step that acts after its step_completed line journals its state after the act
        assert source["event"] in ("step_completed", "sim_state_saved"), name
        assert restored[0]["clock_s"] == source["sim_state"]["clock_s"], name


def test_what_a_simulated_station_keeps_and_refuses(h) -> None:
    """The snapshot goes through the journal's JSON and back; a snapshot that does not fit
    (an edited journal whose chain was re-hashed) is refused by name, not half-restored
    silently; a station on a real-time clock (``resume --speed N``) keeps none."""
    from gyrocal.instruments.sim.station_sim import SimulatedStation
    from gyrocal.models.clock import RealClock, SimClock
    from gyrocal.models.sim_state import SimStateError
    from gyrocal.orchestrator.station import load_station

    station = load_station(h.SIM_STATION)
    with SimulatedStation(station, SimClock(), seed=3, sample_rate_hz=250.0) as sim:
        sim.clock.sleep(12.5)
        state = json.loads(json.dumps(sim.snapshot(), sort_keys=True, allow_nan=False))
        assert state["clock_s"] == 12.5
        sim.clock.sleep(30.0)
        assert sim.restore(state) and sim.clock.now_s() == 12.5
        assert sim.gyro_port.next_frame == state["gyro_port"]["custom"]["next_frame"]
        edited = json.loads(json.dumps(state))
        edited["table"]["custom"]["segments"] = {"dataclass": "os:system", "fields": {}}
        with pytest.raises(SimStateError, match="not one of gyrocal's dataclasses"):
            sim.restore(edited)
        del edited["chamber"]
        with pytest.raises(SimStateError, match="KeyError"):
            sim.restore(edited)
    real = SimulatedStation(station, RealClock(20.0), seed=3, sample_rate_hz=250.0)
    try:
        assert real.snapshot() is None and real.restore(state) is False
    finally:
        real.stop()


def _seq(events: list[dict[str, Any]], event: str, step_id: str) -> int:
    return next(e["seq"] for e in events if e["event"] == event and e.get("step_id") == step_id)


#: shipped procedures on stations with more than chamber, table and gyro, and where each
#: is killed: mid-step (the step is run again as a new attempt; ``cut`` names it), between
#: a step that acts after its step_completed line and the next (after its act and the
#: state journaled then), and in between (the act done, its state not yet journaled).
SHIPPED_KILLS: dict[str, dict[str, Any]] = {
    # the supply's coil channels, the powered unit, the Faraday effect
    "magnetic-sensitivity": {
        "cut": "T01.mag.zero",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.mag.zero')}",
            "after-act": f"after:{_seq(ev, 'sim_state_saved', 'T01.mag.pos')}",
            "before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.mag.pos')}"}},
    # the table on its side in position mode, the inclinometers' noise; the last tilt of a
    # run of them returns the table to 0 deg and rate mode after its step_completed line
    "tilt-linearity": {
        "cut": "T01.tilt2.-25deg",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.tilt2.-25deg')}",
            "before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.tilt1.zero')}"}},
    # the table's drive off (interlock open) after a powered static
    "table-interference": {
        "cut": "T01.interference.off",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.interference.off')}"}},
    # the analog gyro through a SCPI DMM: its reading memory and sample timer
    "kvg25-analog-dmm": {
        "cut": "T01.sf.+50dps",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.sf.+50dps')}"}},
    # the RLG through a SCPI counter: its gates and the pulse phase carried between them
    "rlg-pulse-counter": {
        "cut": "T01.sf.+50dps",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.sf.+50dps')}"}},
    # frequency response (synthesis mode left after step_completed), a powered unit's
    # turn-on cycles (the supply, the start-up delay, each power-on's bias draw)
    "acceptance-series": {
        "cut": "T01.rep.c3",
        "points": lambda ev: {
            "before-state-saved": f"before:{_seq(ev, 'sim_state_saved', 'T01.freq.2Hz')}",
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.rep.c3')}"}},
    # three axes on the fixture, in its second mounting; the remount's state restored
    "imu-5-temps-3-mountings": {
        "cut": "T01.MY.static",
        "points": lambda ev: {
            "mid-step": f"before:{_seq(ev, 'step_completed', 'T01.MY.static')}"}},
}


def killed_and_resumed_equals_uninterrupted(name: str, h, tmp_path: Path, capsys) -> None:
    """The supply, coil, tilt and IMU fixture simulators are restored as the single-axis
    station's are: the shipped procedure, killed where its simulators hold state."""
    procedure = h.REPO_ROOT / "procedures" / f"{name}.yaml"
    reference = tmp_path / "reference"
    assert main(run_args(procedure, reference)) in (0, 1)
    expected = counted_samples(reference)
    expected_results = json.loads((reference / "report" / "results.json").read_text())
    events = h.events(reference)
    plan = h.completed_ids(reference)
    # every step's state is journaled: on its step_completed line or after its act
    with_state = {e["step_id"] for e in events if "sim_state" in e
                  and e["event"] in ("step_completed", "sim_state_saved")}
    assert with_state == set(plan)
    case = SHIPPED_KILLS[name]
    with ForkServer(h.REPO_ROOT) as server:
        for point_name, point in case["points"](events).items():
            out = tmp_path / point_name
            status = server.run(run_args(procedure, out), {CRASH_AT_ENV: point},
                                tmp_path / f"{point_name}.err")
            assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (
                name, point_name, status)
            capsys.readouterr()
            assert main(["resume", str(out)]) in (0, 1), (name, point_name,
                                                          capsys.readouterr())
            _assert_equal_run(h, out, point_name, expected, expected_results, plan=plan,
                              cut_step=case["cut"])


# One class per group of procedures: the suite runs under pytest-xdist's ``loadscope``,
# which keeps a module's functions (a class's methods) on one worker; as one parametrized
# function the seven procedures ran one after another on one worker (minutes of the
# suite's tail); as classes they spread over the workers.
class _KillGroup:
    """Some of ``SHIPPED_KILLS``, each killed and resumed (``names``, parametrized below)."""

    pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]
    names: tuple[str, ...] = ()

    def test_killed_and_resumed(self, name, h, tmp_path, capsys) -> None:
        killed_and_resumed_equals_uninterrupted(name, h, tmp_path, capsys)


def pytest_generate_tests(metafunc) -> None:
    if metafunc.cls is not None and issubclass(metafunc.cls, _KillGroup):
        metafunc.parametrize("name", metafunc.cls.names)


class TestImuFixture(_KillGroup):
    names = ("imu-5-temps-3-mountings",)


class TestAcceptanceSeries(_KillGroup):
    names = ("acceptance-series",)


class TestSupplyCoilAndTilt(_KillGroup):
    names = ("magnetic-sensitivity", "tilt-linearity")


class TestDriveOffAndScpiGyros(_KillGroup):
    names = ("table-interference", "kvg25-analog-dmm", "rlg-pulse-counter")


def test_every_kill_case_is_in_one_group() -> None:
    grouped = [name for group in _KillGroup.__subclasses__() for name in group.names]
    assert sorted(grouped) == sorted(SHIPPED_KILLS)


def test_the_supply_unit_power_tilt_and_imu_fixture_go_back_into_their_snapshot(h) -> None:
    """The simulators beyond chamber, table and gyro keep their state in the snapshot: the
    supply's outputs and the time each was switched on, the powered unit's turn-on draws
    (sim-series: a supply and a unit with a start-up delay), the inclinometers' noise
    stream (sim-tilt), the IMU fixture's mounting and each axis's state (sim-imu); a
    snapshot of one station does not go into another."""
    from gyrocal.instruments.sim.station_sim import SimulatedStation
    from gyrocal.models.clock import SimClock
    from gyrocal.models.imu_model import Mounting
    from gyrocal.models.sim_state import SimStateError
    from gyrocal.orchestrator.station import load_station

    stations = h.REPO_ROOT / "stations"
    series = load_station(stations / "sim-series.yaml")
    with SimulatedStation(series, SimClock(), seed=3, sample_rate_hz=250.0) as sim:
        supply, power = sim.supply_server, sim.source.power
        supply.answer("OUTP ON")
        sim.clock.sleep(5.0)
        power.turn_on_offset_dph(0.0)           # the power-on at 0 s has drawn its offset
        state = json.loads(json.dumps(sim.snapshot(), sort_keys=True, allow_nan=False))
        assert {"supply", "unit_power"} <= set(state)
        supply.answer("OUTP OFF")
        next_offset_dph = power.turn_on_offset_dph(9.0)     # a second power-on draws on
        assert sim.restore(state)
        assert supply.output[1] and supply.on_since_s(1) == 0.0
        assert list(power._offsets) == [0.0]
        assert power.turn_on_offset_dph(9.0) == next_offset_dph     # the same draw again
    tilt = load_station(stations / "sim-tilt.yaml")
    with SimulatedStation(tilt, SimClock(), seed=3, sample_rate_hz=250.0) as sim:
        state = json.loads(json.dumps(sim.snapshot(), sort_keys=True, allow_nan=False))
        first = sim.tilt(np.array([0.0, 0.004])).incl_g
        assert sim.restore(state)
        assert np.array_equal(sim.tilt(np.array([0.0, 0.004])).incl_g, first)
    imu = load_station(stations / "sim-imu.yaml")
    with SimulatedStation(imu, SimClock(), seed=3, sample_rate_hz=250.0) as sim:
        sim.fixture.mount(Mounting(1, 1.0))
        sim.clock.sleep(2.0)
        state = json.loads(json.dumps(sim.snapshot(), sort_keys=True, allow_nan=False))
        axes = [axis["object"]["attrs"]["_index"] for axis in
                state["gyro"]["attrs"]["simulators"]["list"]]
        assert axes == [500, 500, 500]          # each axis brought to now (2 s at 250 Hz)
        sim.fixture.mount(Mounting(0, -1.0))
        assert sim.restore(state) and sim.fixture.mounting == Mounting(1, 1.0)
        with pytest.raises(SimStateError, match="supply"):
            sim.restore({**state, "supply": {}})
