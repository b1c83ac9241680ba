"""QCoDeS's Keysight 34465A driver — written for the real meter, not by us — reads the simulated DMM.

The simulated station of ``stations/sim-kvg25-dmm.yaml`` runs on simulated time:
the table (driven by our ACUTROL3000 driver) turns at a set rate, the KVG25's
analog output (volts = scale factor × rate) comes through the simulated 34465A
on loopback, reached by QCoDeS over ``TCPIP0::127.0.0.1::PORT::SOCKET`` with
pyvisa-py. QCoDeS sets range and NPLC, reads a DC voltage (``volt``) and takes a
timed trace on the sample timer (``timetrace``: ``TRIGger:SOURce BUS``,
``SAMPle:TIMer``, ``SAMPle:COUNt``, ``INIT``, ``*TRG``, ``FETCH?``); what it reads
must be the gyro's output for the table's rate, and its trace must agree with the
stream our own driver (``TruevoltAnalogGyro``) pulls from the same meter.

Command spellings checked below are QCoDeS's own (qcodes 0.58,
qcodes/instrument_drivers/Keysight/private/Keysight_344xxA_submodules.py:
``Keysight344xxA._set_range``, ``_set_NPLC``, ``_get_parameter``, ``TimeTrace``);
the 34465A programming guide was not available (docs/protocol-elements.md).
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

from gyrocal.instruments.gyro.truevolt import TruevoltAnalogGyro
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.station_sim import SimulatedStation
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.orchestrator.station import load_station

REPO = Path(__file__).resolve().parents[3]
RATE_DPS = 8.0
FS_HZ = 50.0                   # the trace's sample timer: 20 ms per reading
NPLC = 0.2                     # 4 ms at 50 Hz mains: below the 20 ms period
N = 400


def _keysight_34465a_class(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """QCoDeS's class (named Keysight34465A since 0.4x, Keysight_34465A before), its
    configuration and home kept in tmp so that importing it writes nothing outside."""
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("QCODES_USER_PATH", str(tmp_path / "qcodes"))
    keysight = importlib.import_module("qcodes.instrument_drivers.Keysight")
    return getattr(keysight, "Keysight34465A", None) or keysight.Keysight_34465A


@pytest.fixture
def rig():
    """The simulated station on sim time, its table turning at RATE_DPS and settled."""
    station = load_station(REPO / "stations" / "sim-kvg25-dmm.yaml")
    clock = SimClock()
    sim = SimulatedStation(station, clock, sample_rate_hz=FS_HZ).start()
    table = Acutrol3000Table(sim.addresses.table)
    try:
        table.close_interlock()
        table.set_rate_mode()
        table.set_rate_dps(RATE_DPS)
        clock.advance_to(clock.now_s() + 5.0)          # 100 deg/s² limit: at rate in 0.08 s
        yield sim, clock
    finally:
        table.close()
        sim.stop()


def _expected_v(sim: SimulatedStation, t_s: float) -> float:
    """The model's output for the table's rate: scale factor × rate × (1 + tempco·ΔT)."""
    model = sim.model
    temp_c = float(np.asarray(sim.chamber_physics.air_temperature_c(np.array([t_s])))[0])
    rate = float(np.asarray(sim.table_physics.rate_dps(t_s)))
    assert rate == pytest.approx(RATE_DPS, abs=0.01)
    return model.scale_factor * rate * (
        1.0 + model.sf_tempco_ppm_per_c * 1e-6 * (temp_c - model.reference_temp_c))


def _our_stream(address: str) -> np.ndarray:
    meter = TruevoltAnalogGyro(address, FS_HZ, range_v=10.0, nplc=NPLC, timeout_s=2.0,
                               retry=RetryPolicy(attempts=2, backoff_s=0.01))
    try:
        meter.flush()
        block = meter.read_samples(N, timeout_s=5.0)
    finally:
        meter.close()
    assert not block.flagged.any()
    return block.rate


@pytest.mark.timeout(60)
def test_qcodes_34465a_reads_the_gyros_volts_and_a_timed_trace(rig, tmp_path, monkeypatch):
    sim, clock = rig
    dmm_sim = sim.gyro_port
    Keysight34465A = _keysight_34465a_class(tmp_path, monkeypatch)
    dmm = Keysight34465A("peer_dmm", sim.addresses.gyro, visalib="@py", terminator="\n",
                         timeout=5, silent=True)
    try:
        idn = dmm.IDN()
        assert (idn["vendor"], idn["model"]) == ("Keysight Technologies", "34465A")
        dmm.range(10.0)
        dmm.NPLC(NPLC)
        assert dmm.range() == 10.0 and dmm.NPLC() == NPLC
        assert dmm.aperture_mode() == "OFF"                    # NPLC switched aperture off
        assert dmm.resolution() == pytest.approx(10.0 * 0.7e-6)   # QCoDeS's own table
        # QCoDeS's spellings, as its driver writes them (qcodes 0.58, see the docstring)
        assert "SENSe:VOLTage:DC:RANGe 10.000000" in dmm_sim.received
        assert "SENSe:VOLT:NPLC 0.200000" in dmm_sim.received

        # one reading now: the KVG25's volts for the table's rate
        volts = dmm.volt()
        expected_now = _expected_v(sim, clock.now_s())
        assert "READ?" in dmm_sim.received

        # a timed trace on the sample timer
        dmm.timetrace_dt(1.0 / FS_HZ)
        dmm.timetrace_npts(N)
        first = len(dmm_sim.received)
        trace = dmm.timetrace()
        expected_trace = _expected_v(sim, clock.now_s())
        sent = dmm_sim.received[first:]
        assert trace.shape == (N,) and np.all(np.isfinite(trace))
        assert np.allclose(dmm.time_axis(), np.arange(N) / FS_HZ)
        for line in ("TRIGger:SOURce BUS", "SAMPle:SOURce TIM", f"SAMPle:TIMer {1.0 / FS_HZ}",
                     f"SAMPle:COUNt {N}", "INIT", "*TRG", "FETCH?"):
            assert line in sent, line
        assert sent.index("INIT") < sent.index("*TRG") < sent.index("FETCH?")
        # QCoDeS put the meter back as it found it (its set_to contexts), read back
        assert dmm.sample.count() == 1 and dmm.trigger.source() == "IMM"

        # our driver's stream from the same meter: the reading noise the checks allow
        ours = _our_stream(sim.addresses.gyro)
        sigma_v = float(np.std(ours))
        assert 0.0 < sigma_v < 0.01 * expected_now              # a noisy, not a wild, signal
        assert volts == pytest.approx(expected_now, abs=5 * sigma_v)
        # the trace and our stream: same level, same spread, both the gyro's output
        standard_error = sigma_v * np.sqrt(2.0 / N)
        assert float(np.mean(trace)) == pytest.approx(float(np.mean(ours)), abs=5 * standard_error)
        assert float(np.mean(trace)) == pytest.approx(expected_trace, abs=5 * sigma_v / np.sqrt(N))
        assert 0.8 < float(np.std(trace)) / sigma_v < 1.25
    finally:
        dmm.close()
