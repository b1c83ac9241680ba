"""The simulated ACUTROL3000 checked with a plain socket client (no driver involved).

Commands are written out literally from TM-8004-C (sections cited per test);
replies are read by the framing TM-8004 §2 (p. 2) and TM-9374A §3.4.2 (p. 34)
describe — two 32-bit words, error code then message length, little-endian
like all the controller's binary data (TM-8004 §5.1.1, p. 206) — unpacked here
with ``struct``, not with the project's codec, so a mistake shared by the
driver and the simulator cannot hide.
"""

import math
import socket
import struct
import threading
import time

import pytest

from gyrocal.instruments.sim.table_server import FAULTS, SimulatedAcutrol
from gyrocal.models.clock import SimClock
from gyrocal.models.table import TablePhysics

pytestmark = pytest.mark.timeout(20)


class FrameClient:
    """Send an LF-terminated command line (TM-8004 §2.4), read one framed reply."""

    def __init__(self, host: str, port: int, timeout_s: float = 2.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)

    def send(self, line: str) -> None:
        self.sock.sendall(line.encode("ascii") + b"\n")

    def _exactly(self, count: int) -> bytes:
        data = b""
        while len(data) < count:
            chunk = self.sock.recv(count - len(data))
            if not chunk:
                raise ConnectionError("server closed the connection")
            data += chunk
        return data

    def read_reply(self) -> tuple[int, str]:
        code, length = struct.unpack("<ii", self._exactly(8))
        body = self._exactly(length)
        assert body.endswith(b"\x00")            # the message is null-terminated
        return code, body[:-1].decode("latin-1")

    def ask(self, line: str) -> tuple[int, str]:
        self.send(line)
        return self.read_reply()

    def ok(self, line: str) -> str:
        code, message = self.ask(line)
        assert code == 0, (line, code, message)
        return message

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def clock():
    return SimClock()


@pytest.fixture
def physics(clock):
    return TablePhysics(clock, max_rate_dps=600.0, max_accel_dps2=50.0)


@pytest.fixture
def sim(physics):
    with SimulatedAcutrol(physics, idn="Acutronic R&D USA,Acutrol3000,T42,2.1") as server:
        yield server


@pytest.fixture
def client(sim):
    c = FrameClient(sim.host, sim.port)
    yield c
    c.close()


def test_resource_string_names_the_listening_port(sim):
    assert sim.resource == f"TCPIP0::127.0.0.1::{sim.port}::SOCKET"
    assert sim.port > 0


def test_every_command_is_answered_with_the_documented_header(client):
    """§2 p. 2: every command gets a response, a setting too (empty message)."""
    client.send("*IDN?")
    raw = client._exactly(8)
    assert raw[:4] == bytes.fromhex("00 00 00 00")                     # error code 0
    text = b"Acutronic R&D USA,Acutrol3000,T42,2.1\x00"
    assert raw[4:] == struct.pack("<i", len(text))
    assert client._exactly(len(text)) == text
    assert client.ask(":Utility:Lockout ON") == (0, "")


def test_rate_profile_through_the_documented_commands(client, clock):
    assert client.ok(":Interlock? 1") == "Open"                  # Table 6 p. 24; §4.5.3 p. 133
    client.ok(":Interlock:Reset")                                # §4.5.6 p. 136: no argument
    client.ok(":INT:CLOS 1")                                     # §4.5.1 p. 131
    assert client.ok(":Interlock? 1") == "Close"
    client.ok(":Mode:Rate 1")                                    # §4.7.5 p. 152
    assert client.ok(":MODE? 1") == "R"                          # §4.7 p. 147
    client.ok(":Limit:Acceleration R,1,25.0")                    # §4.6.2 p. 139
    assert float(client.ok(":LIM:ACC? R,1")) == 25.0
    client.ok(":Demand:Rate 1,100.0")                            # §4.3.6 p. 113
    assert float(client.ok(":DEM:RATE? 1")) == 100.0
    clock.advance_to(2.0)  # 100 / 25 = 4 s ramp: half way
    assert float(client.ok(":Read:Rate? 1")) == pytest.approx(50.0)          # §4.10.5 p. 169
    assert float(client.ok(":READ:POS? 1")) == pytest.approx(0.5 * 25 * 4.0)  # §4.10.4 p. 168
    clock.advance_to(10.0)  # 200 deg ramp + 6 s at 100 = 800 deg -> 80 deg on the dial
    assert float(client.ok(":R:R 1")) == pytest.approx(100.0)   # single letters, no "?"
    assert float(client.ok(":Read:Position? 1")) == pytest.approx(80.0)
    client.ok(":M:O 1")                                          # §4.7.3 p. 150
    clock.advance_to(20.0)
    assert float(client.ok(":Read:Rate? 1")) == 0.0
    assert client.ok(":Mode? 1") == "O"


def test_compound_line_answers_each_query_in_order(client, clock):
    client.ok(":I:C 1;:M:R 1;:D:R 1,30")
    clock.advance_to(5.0)
    rate, position, interlock = client.ok(":Read:Rate? 1;:Read:Position? 1;:Interlock? 1").split(";")
    assert float(rate) == 30.0
    assert float(position) == pytest.approx(0.5 * 50 * 0.6**2 + 30 * 4.4)
    assert interlock == "Close"


@pytest.mark.parametrize("line", [
    ":Demand:Rate 1", ":Demand:Rate 1,fast", ":Mode:Rate 1,2", ":Mode:Rate 3",
    ":Limit:Acceleration Q,1,10", ":Limit:Acceleration R,1,51",
    ":Interlock:Reset 1",          # §4.5.6: the reset takes no axis
])
def test_bad_messages_are_refused_and_flagged_in_the_event_status(client, line):
    client.ok(":Interlock:Close 1;:Mode:Rate 1")
    code, message = client.ask(line)
    assert code != 0 and message == ""
    assert int(client.ok("*ESR?")) & 0b100                       # Table 1 p. 19: bit 2
    assert client.ok("*ESR?") == "0"                             # §3.3: reading clears it
    assert client.ok(f":Query:Error? {code}") != ""              # §4.9.1 p. 163


def test_an_unknown_header_is_answered_never_silent(client):
    code, _ = client.ask(":Bogus:Thing 1")
    assert code != 0
    assert client.ok(f":Query:Error? {code}") == "Undefined header"


def test_synthesis_turns_the_loaded_sinusoid_and_the_readback_follows_it(client, clock):
    """§4.3.4 p. 111 (peak position, Hz, initial phase; query ;-separated as its example),
    §4.7.6 p. 153 (:MODE:SYNT), §4.7 p. 147 (mode letter S). 2 deg at 0.5 Hz, phase 0:
    by hand, rate = 2·2π·0.5·cos(π t) = 2π cos(π t), position = 2 sin(π t)."""
    client.ok(":Interlock:Reset;:INT:CLOS 1")
    client.ok(":DEM:OSC 1,2.0,0.5,0")
    assert [float(v) for v in client.ok(":DEM:OSC? 1").split(";")] == [2.0, 0.5, 0.0]
    client.ok(":MODE:SYNT 1")
    assert client.ok(":Mode? 1") == "S"
    clock.advance_to(1.0)                                        # cos π = −1, sin π = 0
    assert float(client.ok(":Read:Rate? 1")) == pytest.approx(-2 * math.pi, abs=1e-5)
    position_deg = float(client.ok(":Read:Position? 1"))             # [0, 360): 0 or 359.99…
    assert min(position_deg, 360.0 - position_deg) == pytest.approx(0.0, abs=1e-5)
    clock.advance_to(1.5)                                        # cos 1.5π = 0, sin 1.5π = −1
    assert float(client.ok(":R:R 1")) == pytest.approx(0.0, abs=1e-5)
    assert float(client.ok(":R:P 1")) == pytest.approx(358.0, abs=1e-5)
    client.ok(":Mode:Off 1")                                     # §4.7.6: another mode ends it
    assert client.ok(":Mode? 1") == "O"


def test_synthesis_without_an_oscillator_or_beyond_the_limits_is_refused(client):
    client.ok(":Interlock:Reset;:INT:CLOS 1")
    code, _ = client.ask(":Mode:Synthesis 1")
    assert client.ok(f":Query:Error? {code}") == "Settings conflict"
    client.ok(":DEM:OSC 1,1.0,2.0,0")                            # 1·(4π)² = 158 deg/s² > 50
    code, _ = client.ask(":Mode:Synthesis 1")
    assert client.ok(f":Query:Error? {code}") == "Parameter out of range"


def test_position_mode_moves_to_the_demand_at_the_limits_and_reads_back(client, clock):
    """§4.7.4 (position mode), §4.3.5 (position demand), §4.10.4 (position readback).

    From rest at 0 deg to 90 deg with 50 deg/s² and 600 deg/s: too short to reach the
    rate limit, a triangle: peak at √(90/50) = 1.3416 s (45 deg, 67.08 deg/s), at rest
    on 90 deg at 2.6833 s. Then -30 deg (330 on the dial) the shorter way: 120 deg back.
    """
    code, _ = client.ask(":Mode:Position 1")                     # interlock open: refused
    assert client.ok(f":Query:Error? {code}") == "Interlock open"
    client.ok(":Interlock:Close 1")
    client.ok(":Mode:Position 1")
    assert client.ok(":Mode? 1") == "P"
    client.ok(":Demand:Position 1,90")
    clock.advance_to(1.3416408)
    assert float(client.ok(":Read:Position 1")) == pytest.approx(45.0, abs=1e-4)
    clock.advance_to(2.0)       # 90 - 0.5·50·(2.68328 - 2)² = 90 - 25·0.466874 = 78.3282 deg
    assert float(client.ok(":Read:Position 1")) == pytest.approx(78.3282, abs=1e-3)
    code, _ = client.ask(":Demand:Position 1,0")                 # still moving: refused
    assert code != 0
    clock.advance_to(3.0)
    assert float(client.ok(":Read:Position 1")) == pytest.approx(90.0, abs=1e-9)
    client.ok(":Demand:Position 1,-30")
    clock.advance_to(30.0)
    assert float(client.ok(":Read:Position 1")) == pytest.approx(330.0, abs=1e-9)
    client.ok(":Interlock:Open 1")                               # drops to off, at rest
    assert client.ok(":Mode? 1") == "O"


def test_an_interlock_refusal_sets_the_status_byte_interlock_bit(client):
    code, _ = client.ask(":Mode:Rate 1")                         # interlock open
    assert client.ok(f":Query:Error? {code}") == "Interlock open"
    assert int(client.ok("*STB?")) & 1                           # §3.10 p. 19: bit 0 (SI)
    assert int(client.ok("*STB?")) & 1 == 0                      # reading clears it


def test_unknown_fault_names_are_refused(sim):
    assert set(FAULTS) == set(sim.faults.known)
    with pytest.raises(ValueError, match="unknown fault"):
        sim.faults.arm("no_replies")


def test_no_reply_loses_exactly_one_reply(sim, client):
    client.sock.settimeout(0.3)
    sim.faults.arm("no_reply")
    client.send(":Interlock:Close 1")
    with pytest.raises(TimeoutError):
        client.read_reply()
    assert client.ok(":Interlock? 1") == "Close"      # it was executed


def test_late_reply_arrives_after_the_delay(sim, client):
    sim.faults.arm("late_reply", delay_s=0.5)
    client.sock.settimeout(0.1)
    client.send("*IDN?")
    with pytest.raises(TimeoutError):
        client.read_reply()  # not there yet ...
    client.sock.settimeout(3.0)
    assert client.read_reply()[1].startswith("Acutronic")  # ... but it does come
    assert sim.faults.history == ["late_reply"]


def test_garbled_reply_is_framed_but_unreadable(sim, client):
    sim.faults.arm("garbled_reply")
    code, message = client.ask(":Read:Rate? 1")
    assert code == 0 and message.startswith("\x15")
    assert float(client.ok(":Read:Rate? 1")) == 0.0


def test_drop_connection_resets_the_client_and_new_connections_work(sim, client):
    sim.faults.arm("drop_connection")
    client.send("*IDN?")
    with pytest.raises((ConnectionError, OSError)):
        client.read_reply()
    fresh = FrameClient(sim.host, sim.port)
    try:
        assert fresh.ok("*IDN?").startswith("Acutronic")
    finally:
        fresh.close()


def test_error_reply_refuses_the_next_setting_command(sim, client):
    client.ok(":Interlock:Close 1")
    sim.faults.arm("error_reply", code=9)
    assert client.ok("*IDN?").startswith("Acutronic")  # queries do not consume it
    assert client.ask(":Mode:Rate 1") == (9, "")
    assert client.ok(":Mode? 1") == "O"  # the refused command did not run
    client.ok(":Mode:Rate 1")


def test_interlock_fault_stops_a_spinning_table_until_cleared_and_closed(sim, client, clock):
    client.ok(":Interlock:Close 1;:Mode:Rate 1;:Demand:Rate 1,100")
    clock.advance_to(10.0)
    sim.faults.arm("interlock_open", count=None)
    assert client.ok(":Interlock? 1") == "Fault"
    assert int(client.ok("*STB?")) & 1
    clock.advance_to(11.0)  # stopping at 50 deg/s^2
    assert float(client.ok(":Read:Rate? 1")) == pytest.approx(50.0)
    assert client.ask(":Interlock:Close 1")[0] != 0
    assert client.ask(":Mode:Rate 1")[0] != 0
    clock.advance_to(20.0)
    assert float(client.ok(":Read:Rate? 1")) == 0.0
    sim.faults.clear("interlock_open")
    assert client.ok(":Interlock? 1") == "Open"  # still open until closed by command
    client.ok(":Interlock:Reset;:Interlock:Close 1;:Mode:Rate 1")


def test_stop_is_idempotent_and_closes_clients(physics):
    server = SimulatedAcutrol(physics).start()
    c = FrameClient(server.host, server.port)
    assert c.ok("*IDN?")
    port = server.port
    server.stop()
    server.stop()
    with pytest.raises((ConnectionError, OSError)):
        c.ask("*IDN?")
    c.close()
    with pytest.raises(OSError):
        socket.create_connection((server.host, port), timeout=0.5).close()


def test_stop_interrupts_a_pending_late_reply(physics):
    server = SimulatedAcutrol(physics).start()
    server.faults.arm("late_reply", delay_s=30.0)
    c = FrameClient(server.host, server.port)
    c.send("*IDN?")
    time.sleep(0.1)
    stopper = threading.Thread(target=server.stop)
    stopper.start()
    stopper.join(timeout=5.0)
    assert not stopper.is_alive()  # the 30 s delay did not hold the server
    c.close()
