"""The counter input chain against the simulated 53230A (a SCPI server on loopback).

Expected lines are typed from issue 24's description of the counter's timed totalize
and reading memory (``CONFigure:TOTalize:TIMed``, ``DATA:POINts?``, ``DATA:REMove?``);
the 53220A/53230A programming guide was not available, so they are unconfirmed
(docs/protocol-elements.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from gyrocal.instruments.gyro.pulse_counter import CounterPulseGyro
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.counter_server import FAULTS, SimulatedCounter
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.models.clock import SimClock

RATE_DPS = 0.0123456          # 0.0123456 deg/s · 5 ms / (2 arcsec) = 0.111 pulse per readout


def steady(t_s):
    t = np.asarray(t_s, dtype=float)
    return np.full(t.shape, RATE_DPS), np.full(t.shape, np.nan)


@pytest.fixture
def sim():
    with SimulatedCounter(steady, SimClock(), 2.0, FaultInjector(FAULTS)) as server:
        yield server


def _counter(sim):
    return CounterPulseGyro(sim.address, 200.0, pulse_weight_arcsec=2.0, channel=1, timeout_s=1.0,
                            retry=RetryPolicy(attempts=2, backoff_s=0.01))


def test_flush_starts_back_to_back_totalize_gates_of_one_readout(sim):
    counter = _counter(sim)
    counter.flush()
    assert [line for line in sim.received if line != "SYST:ERR?"] == [
        "ABORt", "CONFigure:TOTalize:TIMed 0.005,(@1)", "TRIGger:SOURce IMMediate",
        "TRIGger:COUNt 1", "SAMPle:COUNt 1000000", "INIT"]


def test_whole_pulses_become_deg_per_s_through_the_pulse_weight_and_the_angle_is_kept(sim):
    counter = _counter(sim)
    counter.flush()
    block = counter.read_samples(2000, timeout_s=2.0)
    pulses = block.extra["pulses"]
    assert set(np.unique(pulses)) == {0.0, 1.0}                   # the one-pulse discreteness
    np.testing.assert_allclose(block.rate, pulses * (2.0 / 3600.0) * 200.0)
    true_advance = RATE_DPS * 0.005 / (2.0 / 3600.0)
    # the carried phase: the total count never drifts from the true angle by a pulse or more
    drift = np.cumsum(pulses) - true_advance * np.arange(1, 2001)
    assert np.max(np.abs(drift)) < 1.0
    rms_error = np.sqrt(np.mean((pulses - true_advance) ** 2))
    f = true_advance % 1.0
    assert rms_error == pytest.approx(np.sqrt(f * (1 - f)), rel=0.05)   # Golyaev & Kolbas f(1−f)
    assert np.array_equal(block.index, np.arange(2000))


def test_identity_names_the_pulse_chain_and_the_weight(sim):
    described = _counter(sim).identify().description
    assert described.startswith("pulse input chain: timed totalize through Keysight Technologies,53230A")
    assert "pulse weight 2 arcsec" in described and "gate 5 ms" in described
