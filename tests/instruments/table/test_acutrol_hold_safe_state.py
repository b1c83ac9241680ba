"""The horizontal-axis safe state (``safe_state.stop_table(..., hold=True)``) over the real
ACUTROL3000 driver against a scripted raw-socket peer: confirmed only when the rate reads
back at rest *and* the mode reads back servoing; a table that ends in Off, or no table at
all, is TABLE NOT CONFIRMED SAFE naming why.

Command lines typed from TM-8004-C: :Demand:Rate §4.3.6 p. 113, :Mode:Position §4.7.4
p. 151, :Read:Rate? §4.10.5 p. 169, :Mode? §4.7 p. 147 (letters P, O), :Utility:Lockout
§4.14.2 p. 196. Reply prefix packed by the peer of test_acutrol_acl_bytes (TM-9374A §3.4.2).
"""

from __future__ import annotations

import socket

import pytest

from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.orchestrator.safe_state import stop_table

from .test_acutrol_acl_bytes import AclPeer, reply

pytestmark = pytest.mark.timeout(30)

HOLD = [
    (":Utility:Lockout ON", reply()),
    (":Demand:Rate 1,0.000000", reply()),
    (":Mode:Position 1", reply()),
]


def _hold(script, attempts: int = 1):
    peer = AclPeer(script)
    table = Acutrol3000Table(peer.resource, axis=1, timeout_s=1.0, retry=RetryPolicy(attempts=1))
    try:
        action = stop_table(table, SimClock(), attempts, hold=True)
    finally:
        table.close()
        peer.close()
    assert peer.error is None, peer.error
    assert peer.received == [line for line, _ in script]
    return action


def test_held_at_rest_in_position_mode_is_confirmed_with_what_was_read():
    action = _hold([*HOLD, (":Read:Rate? 1", reply("2.5")),     # still decelerating
                    (":Read:Rate? 1", reply("-0.0030")),
                    (":Mode? 1", reply("P"))])
    assert action.confirmed
    assert action.text == ("table held at rest under servo (horizontal axis; read back "
                           "0.003 deg/s, mode position)")


def test_a_table_that_reads_back_off_is_not_confirmed_safe():
    """At rest but servo off: exactly what a horizontal axis must not be left in."""
    action = _hold([*HOLD, (":Read:Rate? 1", reply("0.0")), (":Mode? 1", reply("O"))])
    assert not action.confirmed
    assert action.text.startswith("TABLE NOT CONFIRMED SAFE")
    assert "servo mode reads back off" in action.text


def test_no_table_listening_is_not_confirmed_safe_naming_the_connection():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]          # closed again: nothing listens there
    table = Acutrol3000Table(f"TCPIP0::127.0.0.1::{port}::SOCKET", timeout_s=0.5,
                             retry=RetryPolicy(attempts=1))
    try:
        action = stop_table(table, SimClock(), 2, hold=True)
    finally:
        table.close()
    assert not action.confirmed and action.attempts == 2
    assert "InstrumentConnectionError" in action.text and "Connection refused" in action.text
