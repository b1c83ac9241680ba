"""`gyrocal sim serve` as a user runs it: a separate process, real drivers, Ctrl-C to stop."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.orchestrator.station import load_station

REPO = Path(__file__).resolve().parents[3]


@pytest.mark.timeout(60)
def test_standalone_servers_answer_the_real_drivers_and_stop_on_ctrl_c(tmp_path):
    written = tmp_path / "live-station.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyrocal", "sim", "serve", "--station", "stations/sim.yaml",
         "--write-station", str(written)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if "station file with these addresses" in line:
                break
        assert written.exists(), "".join(lines) + proc.stderr.read()
        station = load_station(written)
        assert station.chamber.address.startswith("socket://127.0.0.1:")
        with WatlowF4(station.chamber.address, baudrate=115200) as chamber:
            assert chamber.read_setpoint_c() == pytest.approx(22.0, abs=0.1)
        with Acutrol3000Table(station.table.address) as table:
            assert "ACUTROL" in table.identify().description.upper()
        gyro = Stim300Gyro(station.gyro.port, sample_rate_hz=station.gyro.sample_rate_hz,
                           with_temperature=station.gyro.with_temperature,
                           lsb=station.gyro.rate_lsb)
        try:
            block = gyro.read_samples(200, timeout_s=5.0)
            assert len(block) == 200 and block.crc_errors == 0
        finally:
            gyro.close()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, err
        assert "simulators stopped" in out
        assert "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
