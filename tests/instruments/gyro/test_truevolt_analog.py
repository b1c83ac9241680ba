"""The Truevolt DMM input chain against the simulated 34465A (a SCPI server on loopback).

Expected configuration lines are typed from QCoDeS's Keysight 344xxA driver
(qcodes/instrument_drivers/Keysight/private/Keysight_344xxA_submodules.py:
``SENSe:FUNCtion {}`` with ``"VOLT"``, ``SENSe:VOLTage:DC:RANGe``, ``ZERO:AUTO``,
``APERture``, ``TRIGger:SOURce``, ``TRIGger:COUNt``, ``SAMPle:SOURce``, ``SAMPle:TIMer``,
``SAMPle:COUNt``, ``INIT``, ``ABORt``); ``DATA:POINts?``/``DATA:REMove?``/``CALibration:DATE?``
and the 9.9E37 overload value are from the issue's description of the meter —
all unconfirmed against the 34465A programming guide (docs/protocol-elements.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.instruments.gyro.truevolt import TruevoltAnalogGyro
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.truevolt_server import FAULTS, SimulatedTruevolt
from gyrocal.models.clock import SimClock


def ramp_source(t_s):
    """1 V + 0.5 V/s: each reading's value says at which timer instant it was taken."""
    t = np.asarray(t_s, dtype=float)
    return 1.0 + 0.5 * t, np.full(t.shape, np.nan)


@pytest.fixture
def sim():
    with SimulatedTruevolt(ramp_source, SimClock(), FaultInjector(FAULTS)) as server:
        yield server


def _meter(sim, fs_hz=200.0, **kw):
    return TruevoltAnalogGyro(sim.address, fs_hz, range_v=10.0, timeout_s=1.0,
                              retry=RetryPolicy(attempts=2, backoff_s=0.01), **kw)


def test_flush_configures_a_timed_dc_volts_stream_then_starts_it(sim):
    meter = _meter(sim, aperture_s=0.004)
    meter.flush()
    sent = [line for line in sim.received if line != "SYST:ERR?"]
    assert sent == ["ABORt", 'SENSe:FUNCtion "VOLT"', "SENSe:VOLTage:DC:RANGe 10",
                    "SENSe:VOLTage:DC:ZERO:AUTO OFF", "SENSe:VOLTage:DC:APERture 0.004",
                    "TRIGger:SOURce IMM", "TRIGger:COUNt 1", "SAMPle:SOURce TIMer",
                    "SAMPle:TIMer 0.005", "SAMPle:COUNt 1000000", "INIT"]
    assert sim.received.count("SYST:ERR?") == len(sent)     # every setting checked
    meter.close()


def test_readings_are_gap_free_and_timed_by_the_sample_timer(sim):
    meter = _meter(sim)
    meter.flush()
    t_init = sim._t_init
    first = meter.read_samples(300, timeout_s=2.0)
    second = meter.read_samples(300, timeout_s=2.0)
    index = np.concatenate([first.index, second.index])
    assert np.array_equal(index, np.arange(600))                      # none lost, none twice
    volts = np.concatenate([first.rate, second.rate])
    np.testing.assert_allclose(volts, 1.0 + 0.5 * (t_init + index / 200.0), atol=1e-9)
    assert first.flagged_count == 0
    assert any(line.startswith("DATA:REMove? ") for line in sim.received)
    meter.close()


def test_overload_readings_are_kept_flagged_as_bad_samples(sim):
    meter = _meter(sim)
    meter.flush()
    sim.faults.arm("overload", count=1)
    block = meter.read_samples(256, timeout_s=2.0)
    assert block.flagged_count == 256 and np.all(block.rate >= 9.9e37)
    assert meter.read_samples(10, timeout_s=2.0).flagged_count == 0


def test_identity_names_the_chain_the_meter_and_its_calibration_date(sim):
    described = _meter(sim, nplc=0.02).identify().description
    assert described.startswith("analog input chain: DC volts through Keysight Technologies,34465A")
    assert "last calibrated 2026-03-17" in described and "NPLC 0.02" in described


def test_a_stalled_timer_is_a_timeout_naming_what_arrived(sim):
    meter = _meter(sim)
    meter.flush()
    sim.faults.arm("stall", count=None)
    with pytest.raises(Exception) as caught:
        meter.read_samples(50, timeout_s=0.3)
    assert "0 of 50 readings" in str(caught.value)
