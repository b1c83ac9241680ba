"""The engine on its own: in-memory instruments, a hand-written plan, simulated time.

No servers, no procedure files, no CLI: each test builds the few plan steps
it needs, runs ``RunEngine`` on fakes that do what the interfaces promise
(and can be told to misbehave), and reads the journal it wrote. These pin
what the engine does at each step kind when something goes wrong, and where
a second engine on the same folder picks up.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from gyrocal.instruments.errors import InstrumentTimeout
from gyrocal.instruments.factory import Instruments
from gyrocal.instruments.interfaces import ChamberStatus, GyroBlock, Identity, TableStatus
from gyrocal.models.clock import SimClock
from gyrocal.models.imu_model import Mounting
from gyrocal.orchestrator.engine import EnginePolicy, RunEngine
from gyrocal.orchestrator.plan import PlanStep
from gyrocal.orchestrator.run_errors import RunFaultError
from gyrocal.record.run_folder import RunFolder
from gyrocal.record.samples import read_chunks
from gyrocal.record.step_kind import StepKind

FS_HZ = 100.0


@dataclass
class FakeChamber:
    clock: SimClock
    temperature_c: float = 22.0
    setpoint_c: float = 22.0
    alarm: bool = False
    stuck: bool = False            # never reaches its setpoint
    setpoints: list[float] = field(default_factory=list)
    links_reset: int = 0

    def identify(self) -> Identity:
        return Identity("chamber", "fake", "memory", "in-memory chamber")

    def read_temperature_c(self) -> float:
        return self.temperature_c

    def read_setpoint_c(self) -> float:
        return self.setpoint_c

    def set_setpoint_c(self, setpoint_c: float) -> None:
        self.setpoint_c = setpoint_c
        self.setpoints.append(setpoint_c)
        if not self.stuck:
            self.temperature_c = setpoint_c      # an ideal chamber: there at once

    def read_status(self) -> ChamberStatus:
        return ChamberStatus(self.temperature_c, self.setpoint_c, self.alarm,
                             "high limit" if self.alarm else "")

    def reset_link(self) -> None:
        self.links_reset += 1

    def close(self) -> None:
        pass


@dataclass
class FakeTable:
    rate_dps: float = 0.0
    interlock: bool = True
    max_rate_dps: float | None = None      # a table that cannot reach more than this
    stops: int = 0
    links_reset: int = 0

    def identify(self) -> Identity:
        return Identity("table", "fake", "memory", "in-memory table")

    def interlock_closed(self) -> bool:
        return self.interlock

    def open_interlock(self) -> None:
        pass

    def close_interlock(self) -> None:
        pass

    def set_rate_mode(self) -> None:
        pass

    def set_acceleration_limit_dps2(self, accel_dps2: float) -> None:
        pass

    def set_rate_dps(self, rate_dps: float) -> None:
        limit = self.max_rate_dps
        self.rate_dps = rate_dps if limit is None else float(np.clip(rate_dps, -limit, limit))

    def read_rate_dps(self) -> float:
        return self.rate_dps

    def read_position_deg(self) -> float:
        return 0.0

    def read_status(self) -> TableStatus:
        return TableStatus(self.rate_dps, 0.0, self.interlock)

    def stop(self) -> None:
        self.stops += 1
        self.rate_dps = 0.0

    def reset_link(self) -> None:
        self.links_reset += 1

    def close(self) -> None:
        pass


@dataclass
class FakeGyro:
    """Senses the table rate on the axis the fixture puts up (x up unless told)."""

    clock: SimClock
    table: FakeTable
    up: Mounting = Mounting(0, 1.0)
    fail_reads: int = 0             # the next reads time out
    name: str = "gyro"
    _index: int = 0

    def identify(self) -> Identity:
        return Identity("gyro", "fake", "memory", "in-memory gyro")

    def flush(self) -> None:
        pass

    def read_samples(self, n: int, timeout_s: float) -> GyroBlock:
        if self.fail_reads:
            self.fail_reads -= 1
            raise InstrumentTimeout(self.name, "read", "no frames")
        # the controller let n / fs pass (clock.elapse_reading) before it asked
        index = np.arange(self._index, self._index + n)
        self._index += n
        xyz = np.outer(np.ones(n), self.up.up_vector() * self.table.rate_dps)
        return GyroBlock(rate=xyz[:, 0].copy(), counter=(index % 256).astype(np.uint8),
                         index=index, status=np.zeros(n, np.uint8), rate_xyz=xyz)

    def close(self) -> None:
        pass


@dataclass
class Rig:
    clock: SimClock
    chamber: FakeChamber
    table: FakeTable
    gyro: FakeGyro

    @property
    def instruments(self) -> Instruments:
        return Instruments(self.chamber, self.table, self.gyro, self.clock, FS_HZ)


@pytest.fixture
def rig() -> Rig:
    clock = SimClock()
    table = FakeTable()
    return Rig(clock, FakeChamber(clock), table, FakeGyro(clock, table))


def step(step_id: str, kind: StepKind, setpoint_c: float = 30.0, rate_dps: float = 0.0,
         duration_s: float = 2.0, mounting: str | None = None) -> PlanStep:
    return PlanStep(step_id=step_id, kind=kind, source="test", temp_index=0, test_index=None,
                    repeat=1, setpoint_c=setpoint_c, rate_dps=rate_dps, direction="",
                    accel_dps2=50.0, settle_s=0.0, duration_s=duration_s, transition_s=0.0,
                    expected_s=duration_s, max_s=duration_s, start_s=0.0, ramp_c_per_min=60.0,
                    tolerance_c=0.5, hold_s=1.0, max_wait_s=30.0, mounting=mounting)


PLAN = [
    step("T01.ramp", StepKind.RAMP),
    step("T01.soak", StepKind.SOAK),
    step("T01.static", StepKind.STATIC),
    step("T01.sf.+20dps", StepKind.DWELL, rate_dps=20.0),
    step("T01.sf.-20dps", StepKind.DWELL, rate_dps=-20.0),
]
POLICY = EnginePolicy(poll_s=1.0, chunk_s=1.0, block_s=0.5, max_repeats=1, safe_setpoint_c=25.0,
                      pause_poll_s=0.01)


def new_folder(tmp_path: Path) -> RunFolder:
    tmp_path.mkdir(parents=True, exist_ok=True)
    procedure = tmp_path / "procedure.yaml"
    procedure.write_text("# not read by the engine\n")
    return RunFolder.create(tmp_path / "run", procedure, None)


def run(folder: RunFolder, rig: Rig, plan=PLAN, **kwargs) -> str:
    engine = RunEngine(RunFolder.open(folder.path), list(plan), rig.instruments, POLICY, **kwargs)
    try:
        return engine.run()
    finally:
        engine.journal.close()


def events(folder: RunFolder) -> list[dict]:
    return folder.journal_events()


def completed(folder: RunFolder) -> list[str]:
    return [e["step_id"] for e in events(folder) if e["event"] == "step_completed"]


def test_a_clean_plan_runs_every_step_once_and_logs_the_table_rate(tmp_path: Path, rig: Rig) -> None:
    folder = new_folder(tmp_path)
    assert run(folder, rig) == "done"
    assert completed(folder) == [s.step_id for s in PLAN]
    chunks = [e for e in events(folder) if e["event"] == "chunk_written"
              and e["step_id"] == "T01.sf.-20dps"]
    data = read_chunks(folder.path, [c["path"] for c in chunks])
    assert len(data["gyro"]) == 200                        # 2 s at 100 Hz
    assert np.all(data["gyro"] == -20.0) and np.all(data["gyro_x"] == -20.0)
    assert np.all(data["status"] == 0) and np.all(data["gyro_status"] == 0)
    assert rig.table.rate_dps == 0.0                       # stopped at the end


@pytest.mark.parametrize(("arm_at", "failing", "arm", "words"), [
    ("T01.ramp", "T01.ramp", lambda r: setattr(r.chamber, "alarm", True), "alarm"),
    ("T01.ramp", "T01.soak", lambda r: setattr(r.chamber, "stuck", True), "did not stabilise"),
    ("T01.static", "T01.static", lambda r: setattr(r.gyro, "fail_reads", 10), "no frames"),
    ("T01.sf.+20dps", "T01.sf.+20dps", lambda r: setattr(r.table, "max_rate_dps", 5.0),
     "did not reach 20"),
])
def test_a_fault_at_each_step_kind_goes_safe_and_a_new_engine_resumes_there(
        tmp_path: Path, rig: Rig, arm_at: str, failing: str, arm, words: str) -> None:
    folder = new_folder(tmp_path)
    index = [s.step_id for s in PLAN].index(failing)

    def before(s: PlanStep) -> None:
        if s.step_id == arm_at:
            arm(rig)
    with pytest.raises(RunFaultError, match=words):
        run(folder, rig, before_step=before)
    log = events(folder)
    fault = next(e for e in log if e["event"] == "fault")
    assert fault["step_id"] == failing
    assert log[-1]["event"] == "safe_state"
    # "stopped" is now what the read-back confirmed (issue 9), not what was sent
    assert log[-1]["actions"]["table"] == "table stopped (read back 0.000 deg/s)"
    assert log[-1]["confirmed"] == {"table": True, "chamber": True}
    assert rig.table.links_reset == 1 and rig.chamber.links_reset == 1
    assert rig.table.rate_dps == 0.0 and rig.chamber.setpoint_c == 25.0
    assert completed(folder) == [s.step_id for s in PLAN[:index]]

    # the trouble is cleared; a second engine on the same folder continues at the failed step
    rig.chamber.alarm = rig.chamber.stuck = False
    rig.table.max_rate_dps = None
    rig.gyro.fail_reads = 0
    assert run(folder, rig) == "done"
    log = events(folder)
    resumed = [e for e in log if e["event"] == "resumed"]
    if index:      # with nothing completed the second engine simply starts (no resume point)
        assert resumed and resumed[-1]["from_step"] == failing
    else:
        assert not resumed
    assert completed(folder) == [s.step_id for s in PLAN]     # nothing repeated, nothing lost


def test_a_gyro_read_failure_is_one_repeat_then_succeeds(tmp_path: Path, rig: Rig) -> None:
    folder = new_folder(tmp_path)

    def before(s: PlanStep) -> None:
        if s.step_id == "T01.static":
            rig.gyro.fail_reads = 1
    assert run(folder, rig, before_step=before) == "done"
    bad = [e for e in events(folder) if e["event"] == "step_bad"]
    assert [(e["step_id"], e["attempt"]) for e in bad] == [("T01.static", 1)]
    done = next(e for e in events(folder) if e["event"] == "step_completed"
                and e["step_id"] == "T01.static")
    assert done["attempt"] == 2


class Fixture:
    """An operator who mounts what is asked, or (``wrong``) the next axis up."""

    def __init__(self, gyro: FakeGyro, wrong: bool = False) -> None:
        self.gyro, self.wrong, self.asked = gyro, wrong, []

    def request(self, name: str, mounting: Mounting, instruction: str) -> None:
        self.asked.append(name)
        self.gyro.up = Mounting((mounting.up_axis + 1) % 3, mounting.sign) if self.wrong else mounting

    def confirmed(self, name: str) -> bool:
        return True

    def resumed(self, name: str, mounting: Mounting) -> None:
        self.gyro.up = mounting


def test_a_remount_asks_waits_and_checks_the_mounting(tmp_path: Path, rig: Rig) -> None:
    plan = [step("MY.remount", StepKind.REMOUNT, mounting="Y"),
            step("MY.sf.+20dps", StepKind.DWELL, rate_dps=20.0, mounting="Y")]
    fixture = Fixture(rig.gyro)
    folder = new_folder(tmp_path)
    assert run(folder, rig, plan, operator=fixture, mountings={"Y": Mounting(1, 1.0)}) == "done"
    assert fixture.asked == ["Y"]
    log = events(folder)
    names = [e["event"] for e in log]
    assert names.index("operator_needed") < names.index("operator_confirmed")
    check = next(e for e in log if e["event"] == "step_completed" and e["step_id"] == "MY.remount")
    assert check["sensed_up"] == "+Y"

    wrong = new_folder(tmp_path / "wrong")
    with pytest.raises(RunFaultError, match=r"declared IMU \+Y up.*sensed on \+Z"):
        run(wrong, rig, plan, operator=Fixture(rig.gyro, wrong=True),
            mountings={"Y": Mounting(1, 1.0)})
    assert "MY.remount" not in completed(wrong)
