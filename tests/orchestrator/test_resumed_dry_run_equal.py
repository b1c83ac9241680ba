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
test_crash_every_boundary.py.) The shipped procedures whose stations have more
than chamber, table and gyro, each killed where its simulators hold state:
test_shipped_dry_runs.py.
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
from tests.support.dry_run_compare import assert_resumed_equal, counted_samples
from tests.support.short_run import without_report_figures


def run_args(procedure: Path, out: Path) -> list[str]:
    return ["run", str(procedure), "--sim", "--seed", "11", "--out", str(out),
            "--allow-outside-paths"]


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
def test_a_killed_and_resumed_dry_run_equals_the_uninterrupted_one(h, tmp_path, capsys,
                                                                   monkeypatch, fork_server):
    without_report_figures(monkeypatch)     # the in-process runs' reports: nothing reads them
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
    for name, point in points.items():
        out = tmp_path / name
        status = fork_server.run(run_args(procedure, out), {CRASH_AT_ENV: point},
                                 tmp_path / f"{name}.err", figures=False)
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, (name, status)
        capsys.readouterr()
        assert main(["resume", str(out)]) in (0, 1), (name, capsys.readouterr())
        assert_resumed_equal(out, name, expected, expected_results,
                             list(h.SMALL_PLAN), "T01.sf.+20dps")


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
