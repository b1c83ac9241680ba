"""Injected simulator faults through ``gyrocal run --sim``: retried, or safe state and resumable.

Each run is the real command (``gyrocal.cli.main``) against the real
simulators; the fault is armed on those simulators at a chosen moment (see
``conftest.when_table_commanded``). Persistent faults must leave the table
stopped and the chamber at the station's safe setpoint (asserted on the
simulated physics), exit 3 with a message naming the cause, and a run that
``gyrocal resume`` completes once the fault is gone (a resumed run starts new
simulators, which do not carry the fault).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.journal import read_journal
from tests.support.short_run import without_report_figures

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(autouse=True)
def _no_report_figures(monkeypatch) -> None:
    """The runs' and resumes' reports get no figures (~0.5 s of CPU each, 17 reports): what
    is asserted is the fault handling, the safe state and the record; figures of such a
    run (a static, ± scale-factor pairs) are drawn by the session's smoke run and checked
    in tests/reports/."""
    without_report_figures(monkeypatch)


def run(procedure: Path, out: Path, *extra: str, capture=None) -> int:
    return main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "5", *extra],
                on_sim_started=capture)


def assert_table_stopped(sim: Any) -> None:
    table = sim.table_physics
    assert table.mode == "off"
    assert table.demand_dps == 0.0
    # Decelerating at the limit from at most 20 °/s: at rest within a second of clock time.
    assert abs(float(table.rate_dps(sim.clock.now_s() + 2.0))) < 1e-9


def assert_resumes_to_completion(h: Any, out: Path, capture) -> None:
    capture.arm.clear()
    assert main(["resume", str(out)], on_sim_started=capture) == EXIT_OK
    assert h.completed_ids(out)[-1] == h.SMALL_PLAN[-1]
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)
    assert h.manifest(out)["state"] == "done"
    names = [e["event"] for e in h.events(out)]
    assert "resumed" in names and names[-2:] == ["run_completed", "run_closed"]
    h.assert_chunks_intact(out)
    list(read_journal(out / "journal.jsonl"))   # the hash chain verifies across sessions


def fault_event(h: Any, out: Path) -> dict[str, Any]:
    faults = [e for e in h.events(out) if e["event"] == "fault"]
    assert len(faults) == 1, faults
    return faults[0]


def test_small_plan_is_what_the_tests_expect(h: Any, tmp_path: Path, sim_capture) -> None:
    procedure = h.write_procedure(tmp_path)
    out = tmp_path / "run"
    assert run(procedure, out, capture=sim_capture) == EXIT_OK
    assert h.completed_ids(out) == list(h.SMALL_PLAN)
    assert h.manifest(out)["steps"] == list(h.SMALL_PLAN)
    # Soaks jump the simulated clock by minutes; the gap in the gyro stream that
    # leaves must not be counted as lost frames in the step logged after it.
    logged = [e for e in h.events(out) if e["event"] == "step_completed" and "samples" in e]
    assert logged and all(e["lost_frames"] == 0 and e["crc_errors"] == 0 for e in logged)
    assert all(e["samples"] == 2000 for e in logged)   # 8 s at 250 Hz
    assert not [e for e in h.events(out) if e["event"] in ("retry", "step_bad", "fault")]


# -- transient faults: retried with backoff, journaled, the run completes --------------------

TRANSIENT = [
    ("chamber", "no_reply", {"count": 1}),
    ("chamber", "late_reply", {"count": 1, "delay_s": 0.5}),   # later than the 0.3 s timeout
    ("chamber", "drop_connection", {"count": 1}),
    ("chamber", "modbus_exception", {"count": 1, "code": 6}),  # 6: slave busy (transient)
    ("table", "no_reply", {"count": 1}),
    ("table", "late_reply", {"count": 1, "delay_s": 0.5}),
    ("table", "drop_connection", {"count": 1}),
    ("table", "garbled_reply", {"count": 2}),
]


@pytest.mark.parametrize(("role", "fault", "params"), TRANSIENT,
                         ids=[f"{r}-{f}" for r, f, _ in TRANSIENT])
def test_transient_fault_is_retried_and_the_run_completes(h: Any, tmp_path: Path, sim_capture, role: str, fault: str, params: dict[str, Any]) -> None:
    params = dict(params)
    count = params.pop("count")

    def arm(sim: Any) -> None:
        faults = sim.chamber_faults if role == "chamber" else sim.table_faults
        h.when_table_commanded(sim, 20.0, lambda: faults.arm(fault, count=count, **params))

    sim_capture.arm.append(arm)
    out = tmp_path / "run"
    assert run(h.write_procedure(tmp_path), out, capture=sim_capture) == EXIT_OK
    sim = sim_capture.last
    faults = sim.chamber_faults if role == "chamber" else sim.table_faults
    assert faults.history.count(fault) == count, "the fault never fired: nothing was tested"
    retries = [e for e in h.events(out) if e["event"] == "retry"]
    assert len(retries) >= count
    assert {e["instrument"] for e in retries} == {role}
    assert all(e["command"] and e["detail"] for e in retries)
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)
    assert h.manifest(out)["state"] == "done"
    assert not [e for e in h.events(out) if e["event"] in ("fault", "safe_state")]


# -- persistent faults: safe state, exit 3, resumable ------------------------------------------

def arm_alarm(h: Any, sim: Any) -> None:
    h.when_table_commanded(sim, 20.0, lambda: sim.chamber_faults.arm("alarm", count=None))


def arm_interlock(h: Any, sim: Any) -> None:
    h.when_table_commanded(sim, 20.0, lambda: sim.table_faults.arm("interlock_open", count=None))


def arm_stuck_chamber(h: Any, sim: Any) -> None:
    sim.chamber_faults.arm("never_reaches_setpoint", count=None, capacity=0.3)


def arm_second_soak_stuck(h: Any, sim: Any) -> None:
    h.when_chamber_commanded(sim, 27.0, lambda: sim.chamber_faults.arm(
        "never_reaches_setpoint", count=None, capacity=0.3))


def arm_gyro_stall(h: Any, sim: Any) -> None:
    h.when_table_commanded(sim, 20.0, lambda: sim.gyro_faults.arm("stall", count=None))


PERSISTENT = [
    # name, arm, expected (state at fault, step, words in the message)
    ("chamber-alarm", arm_alarm, "logging", "T01.sf.+20dps", "alarm"),
    ("table-interlock", arm_interlock, "spinning", "T01.sf.+20dps", "interlock"),
    ("soak-never-stable", arm_stuck_chamber, "soaking", "T01.soak", "did not stabilise"),
    ("second-soak-never-stable", arm_second_soak_stuck, "soaking", "T02.soak", "did not stabilise"),
    ("gyro-stall", arm_gyro_stall, "logging", "T01.sf.+20dps", "gyro"),
]


@pytest.mark.parametrize(("arm", "state", "step_id", "words"),
                         [p[1:] for p in PERSISTENT], ids=[p[0] for p in PERSISTENT])
def test_persistent_fault_goes_safe_and_resumes(h: Any, tmp_path: Path, sim_capture, capsys, arm, state: str, step_id: str, words: str) -> None:
    procedure = h.write_procedure(tmp_path, max_repeats=1)
    sim_capture.arm.append(lambda sim: arm(h, sim))
    out = tmp_path / "run"
    assert run(procedure, out, capture=sim_capture) == EXIT_FAULT
    err = capsys.readouterr().err
    assert "fault:" in err and words in err and "instruments safe" in err
    assert f"gyrocal resume {out}" in err
    sim = sim_capture.last
    assert_table_stopped(sim)
    assert sim.chamber_physics.setpoint_c == h.SAFE_SETPOINT_C
    fault = fault_event(h, out)
    assert fault["state"] == state and fault["step_id"] == step_id
    assert words in fault["message"]
    safe = [e for e in h.events(out) if e["event"] == "safe_state"]
    # what the read-backs confirmed, not what was sent (issue 9)
    assert safe[-1]["actions"]["table"].startswith("table stopped (read back 0.0")
    assert safe[-1]["actions"]["chamber"] == f"chamber setpoint {h.SAFE_SETPOINT_C:.1f} °C (read back)"
    assert safe[-1]["confirmed"] == {"table": True, "chamber": True}
    assert h.manifest(out)["state"] == "faulted" and words in h.manifest(out)["last_fault"]
    assert step_id not in h.completed_ids(out)
    assert main(["status", str(out)]) == EXIT_OK
    status = capsys.readouterr().out
    assert "state: faulted" in status and f"next: {step_id}" in status and words in status
    assert_resumes_to_completion(h, out, sim_capture)


def test_gyro_stall_is_retried_as_a_repeat_before_the_safe_state(h: Any, tmp_path: Path, sim_capture) -> None:
    procedure = h.write_procedure(tmp_path, max_repeats=1)
    sim_capture.arm.append(lambda sim: arm_gyro_stall(h, sim))
    out = tmp_path / "run"
    assert run(procedure, out, capture=sim_capture) == EXIT_FAULT
    log = h.events(out)
    retries = [e for e in log if e["event"] == "retry"]
    assert [(e["instrument"], e["attempt"]) for e in retries] == [("gyro", 1)]
    assert "read_samples" in retries[0]["command"]
    bad = [e for e in log if e["event"] == "step_bad"]
    assert [(e["step_id"], e["attempt"]) for e in bad] == [("T01.sf.+20dps", 1)]
    fault = fault_event(h, out)
    assert fault["instrument"].startswith("gyro") and "read_samples" in fault["command"]
    started = [e["attempt"] for e in log if e["event"] == "step_started"
               and e["step_id"] == "T01.sf.+20dps"]
    assert started == [1, 2]


def test_chamber_silent_for_good_stops_the_table_and_reports_the_chamber(h: Any, tmp_path: Path, sim_capture, capsys) -> None:
    """A chamber that never answers cannot be sent to its safe setpoint: say so, stop the table."""
    sim_capture.arm.append(lambda sim: h.when_table_commanded(
        sim, 20.0, lambda: sim.chamber_faults.arm("no_reply", count=None)))
    out = tmp_path / "run"
    assert run(h.write_procedure(tmp_path), out, capture=sim_capture) == EXIT_FAULT
    err = capsys.readouterr().err
    # The old main printed "instruments safe" here although the chamber never answered
    # (issue 9, defect 2): the console now says exactly what was not confirmed.
    assert "CHAMBER NOT CONFIRMED SAFE — check it by hand" in err
    assert "INSTRUMENTS NOT CONFIRMED SAFE" in err and "instruments safe" not in err
    sim = sim_capture.last
    assert_table_stopped(sim)
    # ``no_reply`` executes the write and withholds the answer: the controller took the
    # safe setpoint, but the engine could not know it, so it must not claim it did.
    assert sim.chamber_physics.setpoint_c == h.SAFE_SETPOINT_C
    fault = fault_event(h, out)
    assert fault["instrument"].startswith("chamber") and fault["state"] == "logging"
    retries = [e for e in h.events(out) if e["event"] == "retry" and e["instrument"] == "chamber"]
    assert len(retries) >= 2          # the retry budget (3 attempts) was spent first
    actions = [e for e in h.events(out) if e["event"] == "safe_state"][-1]["actions"]
    assert actions["table"].startswith("table stopped (read back 0.0")
    assert actions["chamber"].startswith("CHAMBER NOT CONFIRMED SAFE") and "chamber" in actions["chamber"]
    assert [e for e in h.events(out) if e["event"] == "safe_state"][-1]["confirmed"] == {
        "table": True, "chamber": False}
    assert h.manifest(out)["safe_confirmed"] is False
    assert h.manifest(out)["state"] == "faulted"
    assert_resumes_to_completion(h, out, sim_capture)


# -- gyro frame loss: repeated within the limit, safe state beyond it ---------------------------

def lose_frames_per_block(h: Any, sim: Any, blocks: int | None, per_block: int = 20) -> None:
    """From the +20 °/s command on, drop ``per_block`` frames of each block the gyro writes.

    The simulated gyro is set to make 512-frame blocks (2 s at 250 Hz; a read span's
    frames are otherwise made in larger calls). Blocks that start 3 s
    after the command lie inside the step's first 8 s attempt (it starts after the
    0.2 s spin-up and 1 s settle); 30 frames a block is 1.5 % of that attempt, and
    a block that spills past it is dropped as stale before the next attempt.
    """
    port = sim.gyro_port
    port.span_block_frames = port.block_frames      # the 512-frame blocks counted on here
    source = port.source
    state = {"on": False, "left": blocks, "from_s": 0.0}

    def start() -> None:
        # Frames before the table reached rate and settled are dropped as stale by the
        # simulated gyro, so count only blocks that start after the settle time.
        state["on"] = True
        state["from_s"] = sim.clock.now_s() + 3.0

    def lossy_source(t_s):
        if (state["on"] and t_s[0] >= state["from_s"]
                and (state["left"] is None or state["left"] > 0)):
            sim.gyro_faults.arm("lose_frames", count=per_block)
            if state["left"] is not None:
                state["left"] -= 1
        return source(t_s)

    port.source = lossy_source
    h.when_table_commanded(sim, 20.0, start)


def test_frame_loss_above_threshold_repeats_the_step(h: Any, tmp_path: Path, sim_capture) -> None:
    sim_capture.arm.append(lambda sim: lose_frames_per_block(h, sim, blocks=3, per_block=30))
    out = tmp_path / "run"
    assert run(h.write_procedure(tmp_path, max_loss=0.01), out, capture=sim_capture) == EXIT_OK
    log = h.events(out)
    bad = [e for e in log if e["event"] == "step_bad"]
    assert [(e["step_id"], e["attempt"]) for e in bad] == [("T01.sf.+20dps", 1)]
    injected = sim_capture.last.gyro_port.injected["lose_frames"]
    assert bad[0]["loss_fraction"] > 0.01 and 20 < bad[0]["lost_frames"] <= injected
    done = [e for e in log if e["event"] == "step_completed" and e["step_id"] == "T01.sf.+20dps"]
    assert done[0]["attempt"] == 2 and done[0]["lost_frames"] == 0
    assert all(c.split("/")[-1].startswith("attempt2-") for c in done[0]["chunks"])
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)


def test_frame_loss_beyond_the_repeat_limit_goes_safe(h: Any, tmp_path: Path, sim_capture, capsys) -> None:
    sim_capture.arm.append(lambda sim: lose_frames_per_block(h, sim, blocks=None))
    out = tmp_path / "run"
    assert run(h.write_procedure(tmp_path, max_loss=0.01, max_repeats=2), out,
               capture=sim_capture) == EXIT_FAULT
    assert "no good attempt in 3" in (err := capsys.readouterr().err) and "(limit 1.000%)" in err
    bad = [e for e in h.events(out) if e["event"] == "step_bad"]
    assert [e["attempt"] for e in bad] == [1, 2, 3]
    assert all(e["loss_fraction"] > 0.01 for e in bad)
    fault = fault_event(h, out)
    assert fault["state"] == "ready" and fault["step_id"] == "T01.sf.+20dps"
    assert_table_stopped(sim_capture.last)
    assert sim_capture.last.chamber_physics.setpoint_c == h.SAFE_SETPOINT_C
    assert h.manifest(out)["state"] == "faulted"
    assert_resumes_to_completion(h, out, sim_capture)
    resumed = [e for e in h.events(out) if e["event"] == "step_completed"
               and e["step_id"] == "T01.sf.+20dps"]
    assert resumed[0]["attempt"] == 4     # attempt numbers continue: no chunk overwritten
