"""`gyrocal sim serve` of the analog and pulse stations: every simulator answers the real drivers."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gyrocal.instruments.gyro.pulse_counter import CounterPulseGyro
from gyrocal.instruments.gyro.truevolt import TruevoltAnalogGyro
from gyrocal.instruments.supply.keysight_e36300 import KeysightE36300Supply
from gyrocal.orchestrator.station import load_station

REPO = Path(__file__).resolve().parents[3]


def _serve(station: str, written: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "gyrocal", "sim", "serve", "--station", station,
                             "--write-station", str(written)], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and "station file with these addresses" not in (
            proc.stdout.readline()):
        pass
    assert written.exists(), proc.stderr.read()
    return proc


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 0
    assert "simulators stopped" in proc.stdout.read()


@pytest.mark.timeout(240)
def test_the_dmm_station_serves_volts_on_the_timer_and_its_supply(tmp_path):
    proc = _serve("stations/sim-kvg25-dmm.yaml", tmp_path / "live.yaml")
    try:
        station = load_station(tmp_path / "live.yaml")
        meter = TruevoltAnalogGyro(station.gyro.port, station.gyro.sample_rate_hz, timeout_s=2.0)
        meter.flush()
        block = meter.read_samples(100, timeout_s=5.0)       # 0.5 s of real time at 200 Hz
        assert np.array_equal(block.index, np.arange(100)) and block.flagged_count == 0
        assert np.all(np.abs(block.rate) < 0.01)              # at rest: bias only, volts
        meter.close()
        supply = KeysightE36300Supply(station.supply.address, channel=2)
        assert "E36312A" in supply.identify().description
        supply.close()
    finally:
        if proc.poll() is None:
            _stop(proc)


@pytest.mark.timeout(240)
def test_the_counter_station_serves_whole_pulse_counts(tmp_path):
    proc = _serve("stations/sim-rlg-counter.yaml", tmp_path / "live.yaml")
    try:
        station = load_station(tmp_path / "live.yaml")
        counter = CounterPulseGyro(station.gyro.port, station.gyro.sample_rate_hz,
                                   pulse_weight_arcsec=2.0, timeout_s=2.0)
        counter.flush()
        block = counter.read_samples(100, timeout_s=5.0)
        pulses = block.extra["pulses"]
        assert np.array_equal(pulses, np.round(pulses)) and np.all(np.abs(pulses) <= 1)
        counter.close()
    finally:
        if proc.poll() is None:
            _stop(proc)


@pytest.mark.timeout(240)
@pytest.mark.parametrize("station_file, chain", [("stations/sim-kvg25-dmm.yaml", "analog input chain"),
                                                 ("stations/sim-rlg-counter.yaml", "pulse input chain")])
def test_station_check_covers_the_input_chain_and_the_supply(tmp_path, station_file, chain):
    proc = _serve(station_file, tmp_path / "live.yaml")
    try:
        check = subprocess.run([sys.executable, "-m", "gyrocal", "station", "check",
                                str(tmp_path / "live.yaml"), "--json", str(tmp_path / "c.json")],
                               capture_output=True, text=True, timeout=180, cwd=REPO)
        assert check.returncode == 0, check.stdout + check.stderr
        import json
        report = json.loads((tmp_path / "c.json").read_text())["instruments"]
        assert report["gyro"]["facts"]["identity"].startswith(chain)
        assert report["gyro"]["facts"]["readings"] >= 100 and report["gyro"]["facts"]["bad_readings"] == 0
        assert "E36312A" in report["supply"]["facts"]["identity"]
        assert report["supply"]["facts"]["output_on"] is False     # checked, never switched
    finally:
        if proc.poll() is None:
            _stop(proc)
