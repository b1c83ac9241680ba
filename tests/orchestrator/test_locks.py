"""One controller per run folder and per instrument (issue 9, defect 1).

On the old main ``gyrocal resume R`` beside a running ``gyrocal run --out R``
started a second controller on the same instruments and the journal's hash
chain broke; two runs on one live station both drove its table. Here the
second controller is refused with exit 3 naming the holder, and the first
one finishes and verifies.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.locks import (
    LOCK_DIR_ENV,
    FileLock,
    LockBusyError,
    holder,
    run_folder_lock,
)
from tests.support.fork_server import Forked
from tests.support.sim_serve import served_station, stop

pytestmark = pytest.mark.timeout(120)
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def private_lock_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "locks"
    monkeypatch.setenv(LOCK_DIR_ENV, str(folder))
    return folder


def test_second_lock_is_refused_naming_the_holder_and_released_lock_is_free(tmp_path: Path) -> None:
    first = FileLock(tmp_path / "x.lock", "thing").acquire()
    found = holder(tmp_path / "x.lock")
    assert found is not None and found.pid == os.getpid()
    with pytest.raises(LockBusyError) as refused:
        FileLock(tmp_path / "x.lock", "thing").acquire()    # another open file: flock conflicts
    assert f"pid {os.getpid()}" in str(refused.value) and "thing is in use" in str(refused.value)
    first.release()
    assert holder(tmp_path / "x.lock") is None
    with FileLock(tmp_path / "x.lock", "thing") as again:
        assert again.stale is None                          # released cleanly: no stale record


def test_a_killed_holder_leaves_a_stale_record_not_a_blocking_lock(tmp_path: Path) -> None:
    script = ("import sys, time; from gyrocal.record.locks import run_folder_lock; "
              f"run_folder_lock({str(tmp_path)!r}).acquire(); print('held', flush=True); time.sleep(60)")
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "held"
        assert holder(tmp_path).pid == child.pid
        with pytest.raises(LockBusyError, match=f"pid {child.pid}"):
            run_folder_lock(tmp_path).acquire()
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
        assert holder(tmp_path) is None
        with run_folder_lock(tmp_path) as lock:
            assert lock.stale is not None and lock.stale.pid == child.pid   # the crash is seen
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def wait_for(predicate, proc: subprocess.Popen | Forked, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        assert proc.poll() is None, f"process ended early: {proc.communicate()}"
        time.sleep(0.02)
    raise AssertionError("condition never met")


@pytest.mark.slow
def test_resume_and_report_beside_a_running_run_are_refused_and_the_run_verifies(
        h: Any, tmp_path: Path, capsys, fork_server) -> None:
    procedure = h.write_procedure(tmp_path)
    out = tmp_path / "run"
    run = fork_server.start(["run", str(procedure), "--sim", "--out", str(out), "--seed", "3"],
                            {}, tmp_path / "run.err")     # a process of its own, forked warm
    try:
        # The operator's pause holds the run (and its lock) between steps for as long as
        # the test needs, whatever the machine's speed.
        wait_for(lambda: (out / "journal.jsonl").exists(), run, timeout_s=60)
        (out / "PAUSE").touch()
        wait_for(lambda: '"event":"paused"' in (out / "journal.jsonl").read_text(), run)
        assert holder(out).pid == run.pid
        capsys.readouterr()
        assert main(["resume", str(out)]) == EXIT_FAULT
        err = capsys.readouterr().err
        assert f"pid {run.pid}" in err and "refusing to start a second controller" in err
        assert main(["report", str(out)]) == EXIT_FAULT
        assert f"pid {run.pid}" in capsys.readouterr().err
        (out / "PAUSE").unlink()
        stdout, stderr = run.communicate(timeout=100)
        assert run.returncode in (0, 1), stderr
        assert "Traceback" not in stderr
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert holder(out) is None
    assert main(["verify", str(out)]) == EXIT_OK, capsys.readouterr()


def write_live_procedure(folder: Path, station: Path) -> Path:
    """A short procedure at the live simulator's ambient (22 °C): seconds of real time."""
    path = folder / "live.yaml"
    path.write_text(f"""
version: 1
name: Live station lock test
unit_under_test: {{model: Simulated FOG, serial: SIM-L, output_units: deg/s, nominal_scale_factor: 1.0}}
station: {station}
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults:
  ramp_c_per_min: 5.0
  soak: {{tolerance_c: 1.0, hold: 1 s, max_wait: 5 min}}
  dwell: 2 s
  settle: 1 s
  accel_dps2: 100.0
  sample_rate_hz: 2000
data_quality:
  max_lost_frame_fraction: 0.01
  max_step_repeats: 2
sequence:
  - setpoint_c: 22.0
    tests:
      - {{kind: static, duration: 3 s}}
""")
    return path


@pytest.mark.slow
def test_two_runs_on_one_live_station_the_second_is_refused_naming_the_holder(
        tmp_path: Path, private_lock_dir: Path, capsys, fork_server) -> None:
    env = {**os.environ, LOCK_DIR_ENV: str(private_lock_dir)}
    first = None
    with served_station(tmp_path / "live-station.yaml", env=env, server=fork_server) as live:
        try:
            procedure = write_live_procedure(tmp_path, live)
            first = fork_server.start(["run", str(procedure), "--station", str(live),
                                       "--out", str(tmp_path / "first")], env,
                                      tmp_path / "first.err")
            wait_for(lambda: (tmp_path / "first" / "journal.jsonl").exists(), first)
            capsys.readouterr()
            code = main(["run", str(procedure), "--station", str(live),
                         "--out", str(tmp_path / "second")])
            err = capsys.readouterr().err
            assert code == EXIT_FAULT, err
            assert f"pid {first.pid}" in err and "in use" in err
            assert not (tmp_path / "second").exists()      # refused before anything was written
            stdout, stderr = first.communicate(timeout=100)
            assert first.returncode in (0, 1), stderr
            assert main(["verify", str(tmp_path / "first")]) == EXIT_OK
        finally:
            if first is not None:
                stop(first)
