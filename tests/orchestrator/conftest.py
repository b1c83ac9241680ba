"""Shared pieces for the engine/run tests: a small procedure, a fast station, fault triggers.

The runs go through the real command path (``gyrocal.cli.main`` or a
``python -m gyrocal`` subprocess) against the real simulators on loopback.
Faults are armed on the simulators the command starts, through
``main([...], on_sim_started=sim_capture)``; a trigger arms a fault at a chosen moment of
the run by watching what the engine commands the real simulated physics to do.
"""

from __future__ import annotations

import json
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support.fork_server import ForkServer

REPO_ROOT = Path(__file__).resolve().parents[2]
SIM_STATION = REPO_ROOT / "stations" / "sim.yaml"
GYRO_MODEL = REPO_ROOT / "gyro-models" / "nominal-fog.yaml"

#: The plan the small procedure expands to (checked by ``test_engine_faults``).
SMALL_PLAN = (
    "T01.ramp", "T01.soak", "T01.static", "T01.sf.+20dps", "T01.sf.-20dps",
    "T02.ramp", "T02.soak", "T02.sf.+20dps", "T02.sf.-20dps",
)
SAFE_SETPOINT_C = 25.0


def write_station(folder: Path, *, link_timeout_s: float = 0.3, gyro_timeout_s: float = 1.0,
                  retries: int = 3) -> Path:
    """The simulated station with short link timeouts, so a dead instrument costs ~1 s, not 10."""
    text = SIM_STATION.read_text()
    text = text.replace("../gyro-models/nominal-fog.yaml", str(GYRO_MODEL))
    text = text.replace("timeout_s: 1.0", f"timeout_s: {link_timeout_s}")
    text = text.replace("retries: 3", f"retries: {retries}")
    text = text.replace("with_temperature: true",
                        f"with_temperature: true\n  timeout_s: {gyro_timeout_s}")
    assert str(GYRO_MODEL) in text and f"timeout_s: {link_timeout_s}" in text
    path = folder / "station.yaml"
    path.write_text(text)
    return path


def write_procedure(folder: Path, *, max_repeats: int = 2, max_loss: float = 0.01,
                    max_wait: str = "10 min") -> Path:
    """Two temperatures, a static and a ±20 °/s pair at each: ~1 s of wall time on SimClock."""
    station = write_station(folder)
    text = f"""
version: 1
name: Engine fault test
unit_under_test: {{model: Simulated FOG, serial: SIM-T, output_units: deg/s, nominal_scale_factor: 1.0}}
station: {station}
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults:
  ramp_c_per_min: 5.0
  soak: {{tolerance_c: 0.5, hold: 10 s, max_wait: {max_wait}}}
  dwell: 8 s
  settle: 1 s
  accel_dps2: 100.0
  sample_rate_hz: 250
data_quality:
  max_lost_frame_fraction: {max_loss}
  max_step_repeats: {max_repeats}
sequence:
  - setpoint_c: 23.0
    tests:
      - {{kind: static, duration: 8 s}}
      - {{kind: sf_sweep, rates_dps: [20]}}
  - setpoint_c: 27.0
    tests:
      - {{kind: sf_sweep, rates_dps: [20]}}
"""
    path = folder / "procedure.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="session")
def fork_server() -> Iterator[ForkServer]:
    """One warm ``gyrocal`` fork server per test process (``tests/support/fork_server.py``),
    shared by the tests that kill or signal runs: its start (the package's imports) is ~2 s
    of CPU, paid once per worker instead of once per test."""
    with ForkServer(REPO_ROOT) as server:
        yield server


@pytest.fixture
def procedure(tmp_path: Path) -> Path:
    return write_procedure(tmp_path)


class SimCapture:
    """Collects the simulated stations the commands start, and arms what the test asks for."""

    def __init__(self) -> None:
        self.stations: list[Any] = []
        self.arm: list[Callable[[Any], None]] = []

    def __call__(self, sim: Any) -> None:
        self.stations.append(sim)
        for arm in self.arm:
            arm(sim)

    @property
    def last(self) -> Any:
        return self.stations[-1]


@pytest.fixture
def sim_capture() -> SimCapture:
    """Pass it to ``main([...], on_sim_started=sim_capture)``."""
    return SimCapture()


def when_table_commanded(sim: Any, rate_dps: float, action: Callable[[], None]) -> None:
    """Run ``action`` once, the first time the engine demands ``rate_dps`` of the simulated table."""
    physics = sim.table_physics
    original = physics.set_rate_demand_dps
    fired = threading.Event()

    def set_rate_demand_dps(value: float) -> None:
        original(value)
        if abs(float(value) - rate_dps) < 1e-9 and not fired.is_set():
            fired.set()
            action()

    physics.set_rate_demand_dps = set_rate_demand_dps


def when_chamber_commanded(sim: Any, setpoint_c: float, action: Callable[[], None]) -> None:
    """Run ``action`` once, the first time the engine sets ``setpoint_c`` on the simulated chamber."""
    physics = sim.chamber_physics
    original = physics.set_setpoint
    fired = threading.Event()

    def set_setpoint(value_c: float) -> None:
        original(value_c)
        if abs(float(value_c) - setpoint_c) < 1e-9 and not fired.is_set():
            fired.set()
            action()

    physics.set_setpoint = set_setpoint


def events(run_dir: Path) -> list[dict[str, Any]]:
    from gyrocal.record.run_folder import RunFolder

    return RunFolder.open(run_dir).journal_events()


def manifest(run_dir: Path) -> dict[str, Any]:
    return json.loads((run_dir / "manifest.json").read_text())


def completed_ids(run_dir: Path) -> list[str]:
    return [e["step_id"] for e in events(run_dir) if e["event"] == "step_completed"]


def assert_chunks_intact(run_dir: Path) -> None:
    """Every chunk the journal names exists and hashes to what the journal recorded."""
    from gyrocal.record.journal import sha256_file

    written = [e for e in events(run_dir) if e["event"] == "chunk_written"]
    assert written, "no chunk was journaled"
    for event in written:
        path = run_dir / event["path"]
        assert path.is_file(), f"{path}: journaled (#{event['seq']}) but missing"
        assert sha256_file(path) == event["sha256"], f"{path}: SHA-256 differs from the journal"
    for event in events(run_dir):
        if event["event"] == "step_completed" and "chunks" in event:
            named = {e["path"] for e in written if e["step_id"] == event["step_id"]
                     and e["attempt"] == event["attempt"]}
            assert set(event["chunks"]) == named, event["step_id"]


@pytest.fixture
def h() -> Any:
    """The helpers above, for test modules (``--import-mode=importlib`` cannot import conftest)."""
    return sys.modules[__name__]
