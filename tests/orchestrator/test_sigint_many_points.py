"""Ctrl-C at many points of a real-time run, inside instrument exchanges too (issue 9).

The setting is the lab's: ``gyrocal sim serve`` is a separate process holding
the chamber (Modbus RTU over TCP) and the table (ACUTROL over TCP); the
controller is a separate ``gyrocal run --station`` process reaching them
through a byte-for-byte proxy (``tests/support/tcp_proxy.py``). For each trial
the test waits until the run is in a given step (ramp, soak, spin-up, dwell),
then lets the proxy deliver SIGINT to the controller *after a request has
gone out and before its reply comes back* - the exchange the defect cut in
half, whose late reply was then read as the answer to the safe-setpoint write.

After each exit the simulator is asked directly - not through gyrocal and not
through the proxy - what it is doing: the chamber's set point register
(Watlow F4 register 300, set point 1, deci-degrees; F4 Series User's Manual,
Modbus register list; Espec ChamberConnectLibrary reads the same register)
and the table's measured rate (``:Read:Rate? 1``, TM-8004 §4.10.5 p. 169, its
reply framed as TM-8004 §2 / TM-9374A §3.4.2 say: little-endian error code and
message length, then the message). Both must be at
the safe values, and the console must say so in the words the issue asks for.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from pymodbus.client import ModbusTcpClient
from pymodbus.framer import FramerType

from gyrocal.cli import EXIT_FAULT
from tests.support.fork_server import Forked, ForkServer
from tests.support.sim_serve import served_station
from tests.support.tcp_proxy import ExchangeProxy

REPO = Path(__file__).resolve().parents[2]
SAFE_SETPOINT_C = 25.0

pytestmark = [pytest.mark.timeout(400), pytest.mark.slow]


def write_procedure(folder: Path, station: Path, setpoint_c: float) -> Path:
    """A ramp to ``setpoint_c``, a short soak, a static and a ±50 deg/s pair, in real time.

    Each step only has to last long enough for the signal to land in one of its
    exchanges (a few requests after the test arms the proxy): 2 s holds and dwells,
    and a 1 s spin-up keep the seven trials to seconds of real time each."""
    path = folder / "interrupt-me.yaml"
    path.write_text(f"""
version: 1
name: Interrupt me
unit_under_test: {{model: Simulated FOG, serial: SIM-INT, output_units: deg/s, nominal_scale_factor: 1.0}}
station: {station}
safety:
  chamber: {{min_temp_c: 15.0, max_temp_c: 35.0, max_ramp_c_per_min: 5.0}}
  table: {{max_rate_dps: 200.0, max_accel_dps2: 100.0}}
defaults:
  ramp_c_per_min: 5.0
  soak: {{tolerance_c: 2.0, hold: 2 s, max_wait: 2 min}}
  dwell: 2 s
  settle: 1 s
  accel_dps2: 50.0
  sample_rate_hz: 2000
data_quality:
  max_lost_frame_fraction: 0.001
  max_step_repeats: 1
sequence:
  - setpoint_c: {setpoint_c:.1f}
    tests:
      - {{kind: static, duration: 2 s}}
      - {{kind: sf_sweep, rates_dps: [50]}}
""")
    return path


def tcp_target(address: str) -> tuple[str, int]:
    """``socket://host:port`` or ``TCPIP0::host::port::SOCKET`` → (host, port)."""
    m = re.fullmatch(r"socket://([^:]+):(\d+)", address) or \
        re.fullmatch(r"TCPIP0::([^:]+)::(\d+)::SOCKET", address)
    assert m, address
    return m.group(1), int(m.group(2))


def read_f4_register_c(chamber: tuple[str, int], register: int) -> float:
    """A signed deci-degree F4 register (100 process value, 300 set point 1) read with pymodbus."""
    client = ModbusTcpClient(chamber[0], port=chamber[1], framer=FramerType.RTU, timeout=2)
    assert client.connect()
    try:
        reply = client.read_holding_registers(register, count=1, device_id=1)
        assert not reply.isError(), reply
        raw = reply.registers[0]
        return (raw - 0x10000 if raw & 0x8000 else raw) / 10.0
    finally:
        client.close()


def read_simulator(chamber: tuple[str, int], table: tuple[str, int]) -> tuple[float, float]:
    """The simulator's chamber set point (°C) and table rate (deg/s), asked directly."""
    setpoint_c = read_f4_register_c(chamber, 300)
    with socket.create_connection(table, timeout=2) as sock:
        sock.sendall(b":Read:Rate? 1\n")
        data = b""
        while len(data) < 8 or len(data) < 8 + struct.unpack("<ii", data[:8])[1]:
            chunk = sock.recv(1024)
            assert chunk, "table closed the connection"
            data += chunk
    code, length = struct.unpack("<ii", data[:8])
    assert code == 0, code
    rate_dps = float(data[8:8 + length].rstrip(b"\x00").decode())
    return setpoint_c, rate_dps


def start_controller(argv: list[str], out: Path, server: ForkServer | None
                     ) -> subprocess.Popen | Forked:
    """The ``gyrocal run --station`` process under test: ``python -m gyrocal`` as the lab
    starts it (the first trial), or forked from the warm fork server (the others: a
    process of its own all the same, signalled by its pid, without an interpreter start
    and the package's imports, ~2.5 s of CPU a trial)."""
    if server is not None:
        return server.start(argv, {}, out.parent / f"{out.name}.err")
    return subprocess.Popen([sys.executable, "-m", "gyrocal", *argv], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_step(out: Path, step_id: str, proc: subprocess.Popen | Forked,
                  timeout_s: float = 90) -> None:
    deadline = time.monotonic() + timeout_s
    journal = out / "journal.jsonl"
    while time.monotonic() < deadline:
        if journal.exists() and '"event":"step_started"' in (text := journal.read_text(
                errors="replace")) and f'"step_id":"{step_id}"' in text:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.01)
    raise AssertionError(f"{step_id} never started")


@pytest.fixture
def served(tmp_path: Path, fork_server: ForkServer):
    """``gyrocal sim serve`` in its own process; yields its live station file's content."""
    with served_station(tmp_path / "live.yaml", server=fork_server) as live:
        yield yaml.safe_load(live.read_text())


# (step the run is in, instrument whose exchange the signal lands in, requests after arming,
#  set point above the chamber's present temperature: a 2 °C ramp lasts 24 s at 5 °C/min,
#  0.1 °C makes the ramp short so that later steps are reached quickly)
POINTS = [
    ("T01.ramp", "chamber", 1, 2.0),
    ("T01.ramp", "chamber", 3, 2.0),
    ("T01.soak", "chamber", 2, 0.1),
    ("T01.static", "table", 1, 0.1),
    ("T01.sf.+50dps", "table", 1, 0.1),
    ("T01.sf.+50dps", "table", 3, 0.1),
    ("T01.sf.-50dps", "table", 2, 0.1),
]


def test_sigint_inside_exchanges_at_many_points_leaves_the_simulator_safe(
        served: dict[str, Any], tmp_path: Path, fork_server: ForkServer) -> None:
    chamber = tcp_target(served["chamber"]["address"])
    table = tcp_target(served["table"]["address"])
    proxies = {"chamber": ExchangeProxy(chamber), "table": ExchangeProxy(table)}
    station = dict(served)
    station["chamber"] = {**served["chamber"],
                          "address": f"socket://127.0.0.1:{proxies['chamber'].port}"}
    station["table"] = {**served["table"],
                        "address": f"TCPIP0::127.0.0.1::{proxies['table'].port}::SOCKET"}
    station_path = tmp_path / "proxied-station.yaml"
    station_path.write_text(yaml.safe_dump(station, sort_keys=False))
    hit: list[str] = []
    try:
        for n, (step_id, instrument, after, above_c) in enumerate(POINTS):
            present_c = read_f4_register_c(chamber, 100)
            procedure = write_procedure(tmp_path, station_path, present_c + above_c)
            out = tmp_path / f"run{n}"
            proc = start_controller(["run", str(procedure), "--station", str(station_path),
                                     "--out", str(out)], out, fork_server if n else None)
            try:
                wait_for_step(out, step_id, proc)
                proxies[instrument].arm(after, lambda pid=proc.pid: os.kill(pid, signal.SIGINT))
                _, err = proc.communicate(timeout=120)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.communicate()
            where = f"point {n}: SIGINT in a {instrument} exchange during {step_id}"
            assert proxies[instrument].fired_at_request == after, where   # it did land mid-exchange
            assert proc.returncode == EXIT_FAULT, (where, err)
            assert "Traceback" not in err, (where, err)
            assert "interrupted" in err and f"gyrocal resume {out}" in err, (where, err)
            assert re.search(r"table stopped \(read back -?0\.00\d deg/s\)", err), (where, err)
            assert f"chamber setpoint {SAFE_SETPOINT_C:.1f} °C (read back)" in err, (where, err)
            assert "NOT CONFIRMED" not in err, (where, err)
            setpoint_c, rate_dps = read_simulator(chamber, table)
            assert setpoint_c == SAFE_SETPOINT_C, (where, setpoint_c)
            assert abs(rate_dps) <= 0.01, (where, rate_dps)
            hit.append(where)
    finally:
        for proxy in proxies.values():
            proxy.close()
    assert len(hit) == len(POINTS)
