"""The simulated unit follows the simulated supply's output (the turn-on tests' physics).

Through the real transports: the Keysight E36300 driver over SCPI/TCP to the supply
simulator, the STIM300 driver over a pty. With ``simulation.gyro_startup_s`` the unit
sends nothing while the output is off, its first frame comes that start-up delay after
the output-on, and its warm-up transient (the catalogue's ``warmup_transient``) restarts
at every power-on: the fit of analysis/thermal/warmup.py recovers the hand-typed τ and amplitude
after a first and after a second power cycle.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from gyrocal.analysis.thermal.warmup import fit_warmup
from gyrocal.instruments.errors import InstrumentTimeout
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.station_sim import SimulatedStation
from gyrocal.instruments.supply.keysight_e36300 import KeysightE36300Supply
from gyrocal.models.clock import SimClock
from gyrocal.orchestrator.station import load_station

REPO = Path(__file__).resolve().parents[3]
FS_HZ = 250.0
STARTUP_S = 0.8                  # the stated start-up delay (station simulation.gyro_startup_s)
AMPLITUDE_DPH, TAU_S = 50.0, 30.0  # the hand-typed warm-up truth


def _station(tmp_path: Path):
    model = yaml.safe_load((REPO / "gyro-models" / "nominal-fog.yaml").read_text())
    model["effects"] = [{"name": "warmup_transient", "amplitude_dph": AMPLITUDE_DPH, "tau_s": TAU_S}]
    (tmp_path / "warm.yaml").write_text(yaml.safe_dump(model))
    station = yaml.safe_load((REPO / "stations" / "sim-powered.yaml").read_text())
    station["simulation"]["gyro_model"] = str(tmp_path / "warm.yaml")
    station["simulation"]["gyro_startup_s"] = STARTUP_S
    station["gyro"]["sample_rate_hz"] = FS_HZ
    path = tmp_path / "station.yaml"
    path.write_text(yaml.safe_dump(station))
    return load_station(path, allow_outside=True)


def _read(gyro: Stim300Gyro, clock: SimClock, n: int) -> np.ndarray:
    out: list[np.ndarray] = []
    while (got := sum(b.size for b in out)) < n:
        want = min(5000, n - got)
        clock.elapse_reading(want / FS_HZ)
        out.append(gyro.read_samples(want, timeout_s=10.0).rate)
    return np.concatenate(out)


def _power_on_record(supply, gyro, clock, seconds: float) -> np.ndarray:
    """Switch on, let the start-up delay pass while reading, then read ``seconds`` of data:
    the frame count says when the first frame came."""
    gyro.flush()
    supply.set_output(True)
    clock.elapse_reading(STARTUP_S + 1.0)          # one second of frames after the start-up
    first = gyro.read_samples(int(FS_HZ) - 2, timeout_s=5.0)
    with pytest.raises(InstrumentTimeout):         # ... and not more: nothing came before it
        gyro.read_samples(6, timeout_s=0.5)
    rest = _read(gyro, clock, int(seconds * FS_HZ))
    return np.concatenate((first.rate, rest))


@pytest.mark.timeout(120)
def test_unit_is_silent_while_off_and_restarts_its_warm_up_at_every_power_on(tmp_path):
    station = _station(tmp_path)
    clock = SimClock()
    sim = SimulatedStation(station, clock, sample_rate_hz=FS_HZ).start()
    try:
        supply = KeysightE36300Supply(sim.addresses.supply, channel=1)
        gyro = Stim300Gyro(sim.addresses.gyro, sample_rate_hz=FS_HZ,
                           with_temperature=station.gyro.with_temperature, lsb=station.gyro.rate_lsb)
        try:
            supply.configure(5.0, 0.5)
            supply.set_output(False)
            clock.elapse_reading(3.0)                     # off: three seconds of nothing
            with pytest.raises(InstrumentTimeout):
                gyro.read_samples(1, timeout_s=0.5)
            records = [_power_on_record(supply, gyro, clock, 150.0)]
            supply.set_output(False)
            gyro.flush()                                  # the frames sent before the switch-off
            clock.elapse_reading(20.0)                    # off again: a cool-down
            with pytest.raises(InstrumentTimeout):
                gyro.read_samples(1, timeout_s=0.5)
            records.append(_power_on_record(supply, gyro, clock, 150.0))
        finally:
            gyro.close()
    finally:
        sim.stop()
    for rate_dps in records:
        t_s = STARTUP_S + np.arange(rate_dps.size) / FS_HZ      # from the output-on command
        fit = fit_warmup(t_s, rate_dps * 3600.0, bin_s=1.0)
        # within U (k = 2) of the truth: the second power-on restarted the transient (had it
        # not, its amplitude would be 50·e^(−(150+20)/30) = 0.17 deg/h)
        assert fit.tau_s == pytest.approx(TAU_S, abs=2.0 * fit.u_tau_s), fit
        assert fit.amplitude_dph == pytest.approx(AMPLITUDE_DPH, abs=2.0 * fit.u_amplitude_dph), fit
        assert fit.u_tau_s < 0.1 * TAU_S
