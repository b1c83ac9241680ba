"""The simulated table's powered drive disturbs the simulated gyro; the analysis finds it.

Through the real transports: the ACUTROL driver over SCPI/TCP to the table
simulator, the STIM300 driver over a pty. The station is
stations/sim-table-interference.yaml (the vendor notes' 12.48 Hz family,
30/15/8 deg/h, and 55 deg/h of extra white noise while the drive is powered).
The drive is switched off the way a real table's is when its safety chain
opens: the simulator's ``interlock_open`` fault, read back through the driver
(the RateTable interface on main has no call that opens the interlock).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gyrocal.analysis.environment.interference import compare
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.station_sim import SimulatedStation
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.orchestrator.station import load_station

REPO = Path(__file__).resolve().parents[3]
FS_HZ = 250.0
N = 100_000                     # 400 s per record


def _read(gyro: Stim300Gyro, clock: SimClock, n: int) -> np.ndarray:
    out = []
    while sum(len(b) for b in out) < n:
        want = min(5000, n - sum(len(b) for b in out))
        clock.elapse_reading(want / FS_HZ)     # on simulated time the controller lets it pass
        block = gyro.read_samples(want, timeout_s=10.0)
        assert block.lost_frames == 0 and block.crc_errors == 0
        out.append(block.rate)
    return np.concatenate(out)


@pytest.mark.timeout(120)
def test_the_powered_drive_adds_the_vendor_lines_and_they_vanish_with_it_off():
    station = load_station(REPO / "stations" / "sim-table-interference.yaml")
    clock = SimClock()
    sim = SimulatedStation(station, clock, sample_rate_hz=FS_HZ).start()
    try:
        table = Acutrol3000Table(sim.addresses.table)
        gyro = Stim300Gyro(sim.addresses.gyro, sample_rate_hz=FS_HZ,
                           with_temperature=station.gyro.with_temperature, lsb=station.gyro.rate_lsb)
        try:
            table.close_interlock()
            table.set_rate_mode()
            table.set_rate_dps(0.0)
            assert table.interlock_closed()
            gyro.flush()
            powered = _read(gyro, clock, N)
            sim.table_faults.arm("interlock_open", count=None)
            assert not table.interlock_closed()          # read back: the drive is off
            gyro.flush()
            off = _read(gyro, clock, N)
        finally:
            gyro.close()
            table.close()
    finally:
        sim.stop()
    result = compare(powered * 3600.0, off * 3600.0, FS_HZ)     # deg/s -> deg/h (SF 1)
    found = [(round(line.frequency_hz, 2), line.amplitude_dph) for line in result.lines]
    assert [f for f, _ in found] == [12.48, 24.96, 37.44], found
    # a sine's LS amplitude in white noise s has standard error s·sqrt(2/N): here
    # sqrt(9.49² + 55²)·sqrt(2/1e5) = 0.25 deg/h; allow 4 of them
    tolerance = 4 * np.hypot(9.49, 55.0) * np.sqrt(2.0 / N)
    for (_, amplitude), truth in zip(found, (30.0, 15.0, 8.0), strict=True):
        assert amplitude == pytest.approx(truth, abs=tolerance)
    assert all(line.amplitude_off_dph < 1.0 for line in result.lines)
    # 1-s means: sqrt(9.49^2 + 55^2)/9.49 = 5.9 from the white parts (bias instability and
    # lines add a little to each side)
    assert 4.5 < result.drift_ratio < 7.0, result.drift_ratio
