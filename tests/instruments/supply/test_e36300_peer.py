"""Someone else's driver for the real instrument drives our simulated supply.

PyMeasure's KeysightE36312A (written for the real E36312A) over a raw socket,
so our simulator cannot merely agree with our own driver.
"""

from __future__ import annotations

import pytest
from pymeasure.adapters import VISAAdapter
from pymeasure.instruments.keysight import KeysightE36312A

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.supply_server import FAULTS, SimulatedE36300


def test_pymeasure_e36312a_sets_measures_and_switches_the_simulated_supply():
    with SimulatedE36300(FaultInjector(FAULTS), load_ohm=20.0, noise_a=0.0) as sim:
        adapter = VISAAdapter(sim.address, visa_library="@py", read_termination="\n",
                              write_termination="\n", timeout=2000)
        peer = KeysightE36312A(adapter)
        channel = peer.ch_1
        channel.voltage_setpoint = 5
        channel.current_limit = 0.5
        channel.output_enabled = True
        assert channel.voltage_setpoint == 5.0 and channel.current_limit == 0.5
        assert channel.output_enabled is True
        assert channel.voltage == 5.0
        assert channel.current == pytest.approx(0.25)
        channel.output_enabled = False
        assert channel.current == 0.0
        assert "E36312A" in peer.id
        adapter.close()
