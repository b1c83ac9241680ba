"""A run resumed on another unit under test is refused before its first step.

A night on a real rig: the run is stopped (here killed while paused), and by
morning the fixture holds another STIM300. Before, the resumed run went on
and the report put both units' samples under one certificate (the report
reads only the latest identity). Now the unit's serial, asked with
``I<CR>`` (TS1524 §8.2, Table 5-15), is compared with the serial this run's
earlier sessions journaled: another unit is a fault at connect (exit 3),
nothing measured, and the original unit reconnected resumes and finishes.

The real path: ``gyrocal run --station`` against ``gyrocal sim serve
--unit-serial``, the chamber and table reached through TCP proxies and the
gyro through a symlink under /dev/shm, so the station file (whose SHA-256 a resume checks)
stays the same while the simulators behind it are restarted with another unit.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import tempfile
import time
from pathlib import Path

import pytest
import yaml

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.record.locks import LOCK_DIR_ENV
from tests.support.fork_server import Forked, ForkServer
from tests.support.sim_serve import served_station
from tests.support.tcp_proxy import ExchangeProxy

pytestmark = [pytest.mark.timeout(300), pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
UNIT_A = "N25580000000123"       # TS1524 Table 5-15: the letter N and fourteen digits
UNIT_B = "N25580000000456"


def _host_port(address: str) -> tuple[str, int]:
    """socket://127.0.0.1:PORT (Modbus RTU over TCP) or TCPIP0::127.0.0.1::PORT::SOCKET (VISA)."""
    match = re.search(r"(\d+\.\d+\.\d+\.\d+)::?(\d+)", address)
    assert match, address
    return match.group(1), int(match.group(2))


class StableStation:
    """A station file whose addresses outlive the simulators behind them."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        # a station's gyro port is a device path (/dev/…), as a lab's /dev/serial/by-id link is
        self._links = Path(tempfile.mkdtemp(prefix="gyrocal-unit-", dir="/dev/shm"))
        self.gyro_link = self._links / "gyro-port"
        self.proxies: dict[str, ExchangeProxy] = {}
        self.path = folder / "stable.yaml"

    def point_at(self, live: Path) -> None:
        data = yaml.safe_load(live.read_text(encoding="utf-8"))
        for role in ("chamber", "table"):
            target = _host_port(data[role]["address"])
            if role not in self.proxies:
                self.proxies[role] = ExchangeProxy(target)
            self.proxies[role].target = target          # new connections reach the new server
            data[role]["address"] = data[role]["address"].replace(str(target[1]),
                                                                  str(self.proxies[role].port))
        if self.gyro_link.is_symlink():
            self.gyro_link.unlink()
        self.gyro_link.symlink_to(data["gyro"]["port"])
        data["gyro"]["port"] = str(self.gyro_link)
        text = yaml.safe_dump(data, sort_keys=False)
        if not self.path.exists():
            self.path.write_text(text, encoding="utf-8")
        assert self.path.read_text(encoding="utf-8") == text     # what the run's SHA-256 covers

    def close(self) -> None:
        for proxy in self.proxies.values():
            proxy.close()
        shutil.rmtree(self._links, ignore_errors=True)


def _procedure(folder: Path, station: Path) -> Path:
    path = folder / "unit.yaml"
    path.write_text(f"""
version: 1
name: Resume on the same unit
unit_under_test: {{model: STIM300, serial: {UNIT_A}, output_units: deg/s, nominal_scale_factor: 1.0}}
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
data_quality:
  max_lost_frame_fraction: 0.01
  max_step_repeats: 2
sequence:
  - setpoint_c: 22.0
    tests:
      - {{kind: static, duration: 2 s}}
      - {{kind: static, duration: 2 s}}
""", encoding="utf-8")
    return path


def _events(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]


def _wait(condition, proc: Forked, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.1)


def _start_and_kill_paused(procedure: Path, station: Path, out: Path,
                           server: ForkServer) -> None:
    """Run until the operator's pause holds it (preflight done, the unit identified), then kill -9.
    The run is forked from the warm fork server (a process of its own, killed by its pid)."""
    run = server.start(["run", str(procedure), "--station", str(station), "--out", str(out),
                        "--allow-outside-paths"], {}, out.parent / f"{out.name}.err")
    try:
        _wait(lambda: (out / "journal.jsonl").exists(), run)
        (out / "PAUSE").touch()
        _wait(lambda: '"event":"paused"' in (out / "journal.jsonl").read_text(), run)
    finally:
        os.kill(run.pid, signal.SIGKILL)
        run.communicate()
    (out / "PAUSE").unlink()


def test_a_resume_on_another_unit_is_refused_and_the_original_unit_finishes(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, fork_server) -> None:
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    stable = StableStation(tmp_path)
    procedure = _procedure(tmp_path, stable.path)
    out = tmp_path / "run"
    try:
        with served_station(tmp_path / "live-a.yaml", extra_args=("--unit-serial", UNIT_A), server=fork_server) as live:
            stable.point_at(live)
            _start_and_kill_paused(procedure, stable.path, out, fork_server)
        first = [e for e in _events(out) if e["event"] == "instrument_identified"
                 and e["role"] == "gyro"]
        assert len(first) == 1 and f"serial {UNIT_A}" in first[0]["description"]

        with served_station(tmp_path / "live-b.yaml", extra_args=("--unit-serial", UNIT_B), server=fork_server) as live:
            stable.point_at(live)
            capsys.readouterr()
            code = main(["resume", str(out)])
        err = capsys.readouterr().err
        assert code == EXIT_FAULT, err
        assert (f"gyro: preflight: reports serial {UNIT_B}, but this run began with serial "
                f"{UNIT_A}") in err
        assert "Traceback" not in err
        events = _events(out)
        assert not any(e["event"] == "step_started" for e in events)
        assert any(e["event"] == "fault" and UNIT_B in json.dumps(e) for e in events)

        with served_station(tmp_path / "live-a2.yaml", extra_args=("--unit-serial", UNIT_A), server=fork_server) as live:
            stable.point_at(live)
            code = main(["resume", str(out)])
        err = capsys.readouterr().err
        assert code == EXIT_OK, err
    finally:
        stable.close()
    results = json.loads((out / "report" / "results.json").read_text())
    assert results["instruments"]["gyro"]["reported_serial"] == UNIT_A
    completed = [e["step_id"] for e in _events(out) if e["event"] == "step_completed"]
    plan = json.loads((out / "manifest.json").read_text())["steps"]
    assert completed == plan        # every step once, all measured on unit A
    assert main(["verify", str(out)]) == EXIT_OK


def test_sim_serve_refuses_a_serial_a_stim300_cannot_report(capsys) -> None:
    """``--unit-serial`` must have Table 5-15's form (N and fourteen digits): exit 2, named."""
    code = main(["sim", "serve", "--unit-serial", "SIM-0001"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--unit-serial 'SIM-0001'" in err and "Table 5-15" in err and "Traceback" not in err
