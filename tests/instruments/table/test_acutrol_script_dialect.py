"""The default table dialect, after the one public script that drives a real ACUTROL.

That script (a ROS node for an AC117 table: ``acutrol.py`` with
``ac117.json``) talks raw TCP with CR LF, reads every reply as
``recv(1024)[8:]`` (an 8-character prefix before the value), checks each
start-up command against its expected answer (AcutronicRobotics/acutrol
``ac117.json``: ``{"startup": [[":utility:lockout on", "OK"],
[":interlock:open 1", "OK"], [":interlock:reset 1", "OK"],
[":interlock:close 1", "OK"]], ...}``), spells the readbacks ``:read:rate 1`` and
``:read:position 1`` (no ``?``) and starts a session with remote lockout and
an interlock open/reset/close. The byte-level test below is written from
those conventions by hand; the prefix's content is not known, so the peer
sends one of its own (``A3K#0001``) and the driver must not care.
"""

from __future__ import annotations

import socket
import threading

import pytest

from gyrocal.instruments.errors import (
    InstrumentProtocolError,
    InstrumentSafetyError,
    InstrumentTimeout,
)
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.table_server import SimulatedAcutrol
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.models.table import MODE_RATE, TablePhysics

pytestmark = pytest.mark.timeout(30)


class LinePeer:
    """A loopback server that expects exact CR LF lines and answers exact lines."""

    def __init__(self, script: list[tuple[str, str]]) -> None:
        self.script = list(script)
        self.received: list[str] = []
        self.error: str | None = None
        self._server = socket.socket()
        self._server.bind(("127.0.0.1", 0))
        self._server.listen(1)
        self.port = self._server.getsockname()[1]
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        conn, _ = self._server.accept()
        buffer = b""
        with conn:
            for expected, reply in self.script:
                while b"\r\n" not in buffer:
                    chunk = conn.recv(4096)
                    if not chunk:
                        self.error = f"connection closed before {expected!r}"
                        return
                    buffer += chunk
                line, buffer = buffer.split(b"\r\n", 1)
                self.received.append(line.decode())
                if line.decode() != expected:
                    self.error = f"expected {expected!r}, got {line.decode()!r}"
                    return
                conn.sendall(reply.encode() + b"\r\n")

    def close(self) -> None:
        self._thread.join(5)
        self._server.close()


PREFIX = "A3K#0001"        # 8 characters, content unknown to the driver


def test_session_start_and_a_readback_byte_for_byte() -> None:
    peer = LinePeer([
        (":utility:lockout on", PREFIX + "OK"),
        (":interlock:open 1", PREFIX + "OK"),
        (":interlock:reset 1", PREFIX + "OK"),
        (":interlock:close 1", PREFIX + "OK"),
        (":read:rate 1", PREFIX + "  12.500000"),
        (":demand:rate 1, 20.000000", PREFIX + "OK"),
        (":read:position 1", PREFIX + "359.500000"),
    ])
    table = Acutrol3000Table(f"TCPIP0::127.0.0.1::{peer.port}::SOCKET", timeout_s=1.0,
                             retry=RetryPolicy(attempts=1))
    try:
        assert table.read_rate_dps() == 12.5
        table.set_rate_dps(20.0)
        assert table.read_position_deg() == 359.5
    finally:
        table.close()
        peer.close()
    assert peer.error is None, peer.error
    assert len(peer.received) == 7


def test_a_setting_not_acknowledged_ok_is_a_refusal_naming_the_reply() -> None:
    peer = LinePeer([
        (":utility:lockout on", PREFIX + "OK"), (":interlock:open 1", PREFIX + "OK"),
        (":interlock:reset 1", PREFIX + "OK"), (":interlock:close 1", PREFIX + "OK"),
        (":mode:rate 1", PREFIX + "ERROR interlock open"),
    ])
    table = Acutrol3000Table(f"TCPIP0::127.0.0.1::{peer.port}::SOCKET", timeout_s=1.0,
                             retry=RetryPolicy(attempts=1))
    try:
        with pytest.raises(InstrumentSafetyError) as caught:
            table.set_rate_mode()
        assert caught.value.reply == "ERROR interlock open"
    finally:
        table.close()
        peer.close()


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


@pytest.fixture
def physics(clock) -> TablePhysics:
    return TablePhysics(clock, max_rate_dps=600.0, max_accel_dps2=100.0, rate_noise_dps=1e-4,
                        seed=3)


@pytest.fixture
def sim(physics):
    with SimulatedAcutrol(physics) as server:           # the default dialect
        yield server


def test_the_simulator_speaks_the_default_dialect_and_never_answers_with_silence(sim) -> None:
    with socket.create_connection(("127.0.0.1", sim.port), timeout=2) as sock:
        replies = []
        for line in (":utility:lockout on", ":R:A 1", ":read:rate 1", ":mode:rate 1"):
            sock.sendall(line.encode() + b"\r\n")
            data = b""
            while not data.endswith(b"\r\n"):
                data += sock.recv(4096)
            replies.append(data.decode()[:-2])
    assert all(len(r) > 8 for r in replies)
    values = [r[8:] for r in replies]
    assert values[0] == "OK"
    assert values[1].startswith("ERROR -113")          # unknown header: an answer, not silence
    assert abs(float(values[2])) < 0.01
    assert values[3].startswith("ERROR 201")           # interlock still open: refused, said so


def test_driver_and_simulator_in_the_default_dialect(sim, clock, physics) -> None:
    table = Acutrol3000Table(sim.resource, timeout_s=0.5, retry=RetryPolicy(attempts=2,
                                                                              backoff_s=0.01))
    try:
        assert table.interlock_closed() is True                 # the session start closed it
        table.set_rate_mode()
        assert physics.mode == MODE_RATE
        table.set_acceleration_limit_dps2(50.0)
        table.set_rate_dps(100.0)
        clock.advance_to(5.0)
        assert table.read_rate_dps() == pytest.approx(100.0, abs=0.01)
        status = table.read_status()
        assert status.interlock_closed and status.rate_dps == pytest.approx(100.0, abs=0.01)
        with pytest.raises(InstrumentProtocolError) as caught:
            table.set_rate_dps(700.0)
        assert "-222" in caught.value.reply
        sim.faults.arm("no_reply")
        assert table.read_position_deg() >= 0.0                  # retried after a timeout
        sim.faults.arm("no_reply", count=None)
        with pytest.raises(InstrumentTimeout):
            table.read_rate_dps()
        sim.faults.clear("no_reply")
        table.stop()
        assert physics.demand_dps == 0.0
    finally:
        table.close()


def test_a_dropped_link_mid_spin_reopens_without_opening_the_interlock(sim, clock, physics):
    """The script's start-up opens the interlock; a reconnect mid-dwell must not (only lockout)."""
    table = Acutrol3000Table(sim.resource, timeout_s=0.5, retry=RetryPolicy(attempts=3,
                                                                              backoff_s=0.01))
    try:
        table.set_rate_mode()
        table.set_rate_dps(30.0)
        clock.advance_to(2.0)
        sim.faults.arm("drop_connection")
        assert table.read_rate_dps() == pytest.approx(30.0, abs=0.01)   # on a new session
        assert physics.interlock_closed and physics.demand_dps == 30.0
        assert sim.faults.history == ["drop_connection"]
    finally:
        table.close()


def test_a_garbled_acknowledgement_repeats_the_idempotent_setting(sim, physics):
    table = Acutrol3000Table(sim.resource, timeout_s=0.5, retry=RetryPolicy(attempts=3,
                                                                              backoff_s=0.01))
    try:
        table.set_rate_mode()
        sim.faults.arm("garbled_reply")
        table.set_rate_dps(12.0)                    # the garbled OK is retried, not a refusal
        assert physics.demand_dps == 12.0
    finally:
        table.close()
