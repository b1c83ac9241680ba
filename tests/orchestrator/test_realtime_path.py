"""The real-time path end to end: a short procedure at --speed 1 against `gyrocal sim serve`
(a separate process, reached through the live station file it writes) and at --speed 20.

Before issue 8 only ``--speed max`` was right: on a real clock the simulated
gyro replayed stale frames (a 20 s step logged in 0.1 s wall) and the report
computed SF ≈ 1e-6 against a true 1.0. Here the report must recover the
simulated truth within 100 ppm, every logged step must be plausible in wall
time (no ``gyro_implausible`` event), and each step must hold exactly its
samples. These tests run in real time (≈ 10 s of procedure time each).

Under load (issue 28) the same run at --speed 20 logged the end of the table's
ramp as the first 80-90 samples of a dwell and still said PASS with SF
1000-3000 ppm off; ``test_under_load_…`` loads the machine itself (CPU and I/O
hogs, tests/support/load.py) and holds the contract that matters: a dwell
holds only samples of its rate, and a PASS is never off by more than its U.
"""

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_OK, main
from gyrocal.errors import EXIT_FAULT
from gyrocal.models.gyro_model import load_model
from tests.support.load import machine_load
from tests.support.sim_serve import served_station

REPO = Path(__file__).resolve().parents[2]
FS_HZ = 2000
DWELL_S = 2      # 4,000 samples a dwell at 2 kHz: the SF to ~1 ppm, far inside the 100 ppm asked


def short_procedure(folder: Path, station: Path, fs_hz: int = FS_HZ, repeats: int = 1) -> Path:
    """One temperature at the simulated ambient, one ±100 deg/s pair: 10 s of procedure time."""
    path = folder / "short.yaml"
    path.write_text(f"""
version: 1
name: Real-time path check
unit_under_test: {{model: Simulated FOG, serial: SIM-RT, output_units: deg/s, nominal_scale_factor: 1.0}}
station: {station}
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults:
  ramp_c_per_min: 5.0
  soak: {{tolerance_c: 2.0, hold: 1 s, max_wait: 1 min}}
  dwell: {DWELL_S} s
  settle: 1 s
  accel_dps2: 100.0
  sample_rate_hz: {fs_hz}
data_quality:
  max_lost_frame_fraction: 0.001
  max_step_repeats: {repeats}
sequence:
  - setpoint_c: 22.0
    tests:
      - {{kind: sf_sweep, rates_dps: [100]}}
""")
    return path


def check_run(out: Path, h: Any, fs_hz: int = FS_HZ, lost_frames_allowed: bool = False) -> None:
    events = h.events(out)
    assert not [e for e in events if e["event"] == "gyro_implausible"]   # nothing stale, ever
    bad = [e for e in events if e["event"] == "step_bad"]
    if lost_frames_allowed:
        # 20x real time is 20x the frame rate through the pty: a host busy with other work may
        # drop frames (counted, the step repeated), but never pass them off as data
        assert all(e["lost_frames"] > 0 and "lost" in e["reason"] for e in bad), bad
    else:
        assert not bad
    done = [e for e in events if e["event"] == "step_completed" and ".sf." in e["step_id"]]
    assert len(done) == 2 and all(e["samples"] == DWELL_S * fs_hz for e in done)
    results = json.loads((out / "report" / "results.json").read_text())
    [entry] = results["scale_factor"]
    truth = true_sf(entry["sensor_temp_c"])
    assert abs(entry["sf"] / truth - 1.0) < 100e-6, (entry["sf"], truth)


def true_sf(sensor_temp_c: float) -> float:
    """The simulated gyro's scale factor at its sensor temperature (its model file)."""
    model = load_model(REPO / "gyro-models" / "nominal-fog.yaml")
    return 1.0 + 1e-6 * (model.sf_error_ppm + model.sf_tempco_ppm_per_c
                         * (sensor_temp_c - model.reference_temp_c))


@pytest.mark.slow
@pytest.mark.timeout(150)
def test_speed_1_against_sim_serve_through_a_live_station_file(h: Any, tmp_path: Path,
                                                               fork_server) -> None:
    with served_station(tmp_path / "live-station.yaml", server=fork_server) as live:
        out = tmp_path / "run"
        code = main(["run", str(short_procedure(tmp_path, live)), "--station", str(live),
                     "--out", str(out)])
        assert code == EXIT_OK
        check_run(out, h)


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_speed_20_in_process(h: Any, tmp_path: Path) -> None:
    out = tmp_path / "run"
    # 500 Hz at 20x is 10,000 frames a wall second (2 kHz would be 40,000: frames lost on a
    # loaded CI machine); four repeats allowed for the frames such a machine may still lose
    # (with two, one of four runs on the 2-core dev machine failed right after another
    # real-time test). A host too busy to feed the stream within 2 s of clock (0.1 s wall)
    # in five attempts gives up with exit 3 (issue 28): honest, never a PASS.
    procedure = short_procedure(tmp_path, REPO / "stations" / "sim.yaml", fs_hz=500, repeats=4)
    code = main(["run", str(procedure), "--sim", "--speed", "20", "--out", str(out)])
    check_never_wrong(out, h, code)
    if code == EXIT_OK:
        check_run(out, h, fs_hz=500, lost_frames_allowed=True)


def off_rate_samples(out: Path, events: list[dict[str, Any]]) -> dict[str, int]:
    """Per completed dwell, the samples farther than 0.05 deg/s from its rate.

    The simulated gyro's noise at 500 Hz is 0.004 deg/s (1 σ) and its bias and SF
    error together under 0.01 deg/s at 100 deg/s, so only a sample taken while
    the table was still accelerating lies that far off.
    """
    off = {}
    for e in events:
        if e["event"] == "step_completed" and ".sf." in e["step_id"]:
            rate_dps = 100.0 if ".sf.+" in e["step_id"] else -100.0
            gyro = np.concatenate([pq.read_table(out / p, columns=["gyro"]).column("gyro")
                                   .to_numpy() for p in e["chunks"]])
            off[e["step_id"]] = int(np.count_nonzero(np.abs(gyro - rate_dps) > 0.05))
    return off


def check_never_wrong(out: Path, h: Any, code: int) -> None:
    """The contract under any load: a dwell holds only samples of its rate, a step is
    repeated only for lost or implausible frames, the run ends OK or gives up (exit 3) for
    data quality, and a PASS is never off the true scale factor by more than its U."""
    events = h.events(out)
    completed = [e["step_id"] for e in events
                 if e["event"] == "step_completed" and ".sf." in e["step_id"]]
    assert off_rate_samples(out, events) == dict.fromkeys(completed, 0)
    bad = [e["reason"] for e in events if e["event"] == "step_bad"]
    assert all("lost" in r or "implausible" in r for r in bad), bad
    assert code in (EXIT_OK, EXIT_FAULT), code
    if code == EXIT_FAULT:
        [fault] = [e for e in events if e["event"] == "fault"]
        assert "no good attempt" in fault["message"], fault
        assert not (out / "report" / "results.json").exists()
        return
    results = json.loads((out / "report" / "results.json").read_text())
    [entry] = results["scale_factor"]
    if results["verdict"]["overall"] == "PASS":
        error = abs(entry["sf"] - true_sf(entry["sensor_temp_c"]))
        assert error <= entry["U"], (entry["sf"], entry["U"], error)


@pytest.mark.slow
@pytest.mark.timeout(150)
@pytest.mark.parametrize("speed", ["20", "5"])
def test_under_load_a_dwell_holds_only_its_rate_and_never_passes_off_by_more_than_u(
        h: Any, tmp_path: Path, speed: str) -> None:
    """Two CPU hogs and an I/O hog for the run (bounded, ended by the test).

    The run may lose frames and repeat a step, or give up with exit 3 (a
    loaded host cannot always feed thousands of frames a wall second in time):
    that is honest. What it may never do is log samples from before the table
    was at rate, or say PASS with a scale factor off by more than its U.
    """
    out = tmp_path / "run"
    procedure = short_procedure(tmp_path, REPO / "stations" / "sim.yaml", fs_hz=500, repeats=2)
    with machine_load(cpu=2, io=1, max_s=100):
        code = main(["run", str(procedure), "--sim", "--speed", speed, "--out", str(out)])
    check_never_wrong(out, h, code)
