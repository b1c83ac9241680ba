"""Every VISA TCP/IP session the drivers open has Nagle off, as VISA's default says.

VPP-4.3 gives ``VI_ATTR_TCPIP_NODELAY`` the default true; pyvisa-py's socket
sessions left the socket's default (Nagle on), so a checked SCPI setting (the
setting, then ``SYST:ERR?``: two small writes before a read) waited for the
instrument's delayed ACK, about 40 ms each (a DMM stream setup of 11 lines
took 0.5 s at every flush; the KVG25 dry run spent 8 of its 16 s there). The
attribute is read back through pyvisa's public ``get_visa_attribute``, which
pyvisa-py answers from the socket itself; the servers are the real simulators.
"""

from __future__ import annotations

from pyvisa import constants as visa_constants

from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.scpi_link import ScpiLink
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.supply_server import FAULTS, SimulatedE36300
from gyrocal.instruments.sim.table_server import SimulatedAcutrol
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.models.table import TablePhysics

NODELAY = visa_constants.ResourceAttribute.tcpip_nodelay


def test_a_scpi_link_session_has_nagle_off() -> None:
    with SimulatedE36300(FaultInjector(FAULTS), load_ohm=20.0, noise_a=0.0) as sim:
        link = ScpiLink(sim.address, "supply", 0.5, RetryPolicy(attempts=1))
        try:
            assert link.ask("*IDN?")
            assert link._session.get_visa_attribute(NODELAY) == visa_constants.VI_TRUE
            link.send("VOLT 5,(@1)")            # a checked setting still works through it
        finally:
            link.reset()


def test_the_table_session_has_nagle_off() -> None:
    clock = SimClock()
    physics = TablePhysics(clock, max_rate_dps=600.0, max_accel_dps2=100.0,
                           rate_noise_dps=0.0, seed=1)
    with SimulatedAcutrol(physics, idn="ACUTRONIC,ACUTROL3000-SIM,SN1,3.0") as sim:
        table = Acutrol3000Table(sim.resource, timeout_s=0.5, retry=RetryPolicy(attempts=1))
        try:
            table.identify()
            assert table._session.get_visa_attribute(NODELAY) == visa_constants.VI_TRUE
        finally:
            table.close()

