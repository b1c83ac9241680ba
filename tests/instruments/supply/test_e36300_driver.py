"""The E36300 supply driver against the simulated supply (a SCPI server on loopback).

Expected lines are typed from PyMeasure's KeysightE36312A driver
(pymeasure/instruments/keysight/keysightE36312A.py: ``VOLT %g, (@{ch})``,
``CURR %g, (@{ch})``, ``OUTPut %d, (@{ch})``, ``OUTPut? (@{ch})``,
``MEASure:VOLTage? (@{ch})``, ``MEAS:CURRent? (@{ch})``), the E36300 programming
guide being unavailable (docs/protocol-elements.md: unconfirmed), and from
SCPI-99 for ``SYST:ERR?``.
"""

from __future__ import annotations

import pytest

from gyrocal.instruments.errors import InstrumentError, InstrumentProtocolError
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.supply_server import FAULTS, SimulatedE36300
from gyrocal.instruments.supply.keysight_e36300 import KeysightE36300Supply


@pytest.fixture
def sim():
    with SimulatedE36300(FaultInjector(FAULTS), load_ohm=20.0, noise_a=0.0) as server:
        yield server


def _driver(sim, channel=1):
    return KeysightE36300Supply(sim.address, channel=channel, timeout_s=0.5,
                                retry=RetryPolicy(attempts=2, backoff_s=0.01))


def test_configure_sends_level_then_error_query_then_reads_the_level_back(sim):
    supply = _driver(sim, channel=2)
    supply.configure(5.0, 0.5)
    assert sim.received == ["VOLT 5, (@2)", "SYST:ERR?", "VOLT? (@2)",
                            "CURR 0.5, (@2)", "SYST:ERR?", "CURR? (@2)"]
    supply.close()


def test_output_on_powers_the_unit_and_reads_volts_amps_and_state(sim):
    supply = _driver(sim)
    supply.configure(5.0, 0.5)
    supply.set_output(True)
    reading = supply.read()
    assert sim.received[-5:] == ["OUTP 1, (@1)", "SYST:ERR?", "OUTP? (@1)", "MEAS:VOLT? (@1)",
                                 "MEAS:CURR? (@1)"]
    assert reading.output_on and reading.voltage_v == 5.0
    assert reading.current_a == pytest.approx(0.25)      # 5 V into the simulated 20 Ω unit
    assert "E36312A" in supply.identify().description
    supply.close()


def test_a_refused_level_is_an_error_naming_the_scpi_code(sim):
    supply = _driver(sim, channel=1)
    with pytest.raises(InstrumentProtocolError) as caught:
        supply.configure(12.0, 0.5)                       # channel 1 is rated 6 V
    assert "-222" in str(caught.value) and "VOLT 12, (@1)" in str(caught.value)


def test_overcurrent_puts_the_supply_at_its_limit_and_dropout_switches_it_off(sim):
    supply = _driver(sim)
    supply.configure(5.0, 0.3)
    supply.set_output(True)
    sim.faults.arm("overcurrent", count=None, factor=3.0)  # the unit draws 0.75 A
    reading = supply.read()
    assert reading.current_a == pytest.approx(0.3) and reading.voltage_v == pytest.approx(2.0)
    sim.faults.clear()
    sim.faults.arm("dropout", count=None)
    assert not supply.read().output_on
    supply.close()


def test_a_silent_supply_times_out_after_the_retries(sim):
    supply = _driver(sim)
    sim.faults.arm("no_reply", count=None)
    with pytest.raises(InstrumentError) as caught:
        supply.read()
    assert "no reply" in str(caught.value)
