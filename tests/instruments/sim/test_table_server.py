"""The simulated ACUTROL3000 checked with a plain socket client (no driver involved).

The command strings here are written out literally from the documented
command set, so a mistake shared by the driver and the simulator cannot hide.
"""

import socket
import threading
import time

import pytest

from gyrocal.instruments.sim.table_server import FAULTS, SimulatedAcutrol
from gyrocal.models.clock import SimClock
from gyrocal.models.table import TablePhysics

pytestmark = pytest.mark.timeout(20)


class LineClient:
    """Minimal line-oriented TCP client: send a line, read one reply line."""

    def __init__(self, host: str, port: int, timeout_s: float = 2.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        self.buffer = b""

    def send(self, line: str) -> None:
        self.sock.sendall(line.encode("ascii") + b"\n")

    def read_line(self) -> str:
        while b"\n" not in self.buffer:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("server closed the connection")
            self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\n", 1)
        return line.decode("latin-1")

    def ask(self, line: str) -> str:
        self.send(line)
        return self.read_line()

    def command(self, line: str) -> None:
        """Send settings and wait until they ran (the error query answers after them)."""
        assert self.ask(line + ";:syst:err?") == '0,"No error"'

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
    # the SCPI error-queue dialect's wire behaviour; the acknowledged one is below
    with SimulatedAcutrol(physics, idn="ACUTRONIC,ACUTROL3000-SIM,T42,2.1",
                          dialect="scpi-error-queue") as server:
        yield server


@pytest.fixture
def client(sim):
    c = LineClient(sim.host, sim.port)
    yield c
    c.close()


def test_resource_string_names_the_listening_port(sim):
    assert sim.resource == f"TCPIP0::127.0.0.1::{sim.port}::SOCKET"
    assert sim.port > 0


def test_identify_and_empty_error_queue(client):
    assert client.ask("*IDN?") == "ACUTRONIC,ACUTROL3000-SIM,T42,2.1"
    assert client.ask(":syst:err?") == '0,"No error"'


def test_rate_profile_through_the_documented_commands(client, clock):
    assert client.ask(":interlock? 1") == "0"
    client.send(":interlock:close 1")
    assert client.ask(":interlock? 1") == "1"
    client.send(":mode:rate 1")
    assert client.ask(":MODE? 1") == "RATE"
    client.send(":limit:acc rate,1, 25")
    assert float(client.ask(":limit:acc? rate,1")) == 25.0
    client.command(":demand:rate 1,   100")  # whitespace after the comma is tolerated
    assert float(client.ask(":demand:rate? 1")) == 100.0
    clock.advance_to(2.0)  # 100 / 25 = 4 s ramp: half way
    assert float(client.ask(":read:rate? 1")) == pytest.approx(50.0)
    assert float(client.ask(":READ:POS? 1")) == pytest.approx(0.5 * 25 * 4.0)
    clock.advance_to(10.0)  # 200 deg ramp + 6 s at 100 = 800 deg -> 80 deg on the dial
    assert float(client.ask(":R:R 1")) == pytest.approx(100.0)  # single-letter form, no "?"
    assert float(client.ask(":read:pos? 1")) == pytest.approx(80.0)
    client.command(":mode:off 1")
    clock.advance_to(20.0)
    assert float(client.ask(":read:rate? 1")) == 0.0
    assert client.ask(":syst:err?") == '0,"No error"'


def test_compound_line_answers_each_query_in_order(client, clock):
    client.command(":int:close 1;:m:r 1;:d:r 1, 30")
    clock.advance_to(5.0)
    rate, position, interlock = client.ask(":read:rate? 1;:read:pos? 1;:interlock? 1").split(";")
    assert float(rate) == 30.0
    assert float(position) == pytest.approx(0.5 * 50 * 0.6**2 + 30 * 4.4)
    assert interlock == "1"
    assert client.ask(":dem:rate 1, 40;:syst:err?") == '0,"No error"'


@pytest.mark.parametrize(
    ("line", "code"),
    [
        (":bogus:thing 1", "-113"),
        (":demand:rate 1", "-109"),
        (":demand:rate 1, fast", "-104"),
        (":mode:rate 1, 2", "-108"),
        (":mode:rate 3", "-222"),
        (":limit:acc pos,1, 10", "-224"),
        (":limit:acc rate,1, 51", "-222"),
    ],
)
def test_malformed_or_out_of_range_commands_queue_scpi_errors(client, line, code):
    client.send(":interlock:close 1;:mode:rate 1")
    client.send(line)
    reply = client.ask(":syst:err?")
    assert reply.startswith(code + ",\"")
    assert client.ask(":syst:err?") == '0,"No error"'


def test_refusals_name_their_reason(client):
    client.send(":interlock:close 1")
    assert client.ask(":demand:rate 1, 10;:syst:err?").startswith('-221,"Settings conflict')
    client.send(":mode:rate 1")
    out_of_range = client.ask(":demand:rate 1, 600.5;:syst:err?")
    assert out_of_range.startswith('-222,"Data out of range')
    assert out_of_range.isascii() and "600.5" in out_of_range
    client.send(":interlock:open 1")
    assert client.ask(":demand:rate 1, 10;:syst:err?").startswith('201,"Interlock open')
    assert client.ask(":mode:rate 1;:syst:err?").startswith("201,")


def test_star_cls_clears_the_queue(client):
    client.send(":nope")
    client.send(":nope")
    client.send("*CLS")
    assert client.ask(":syst:err?") == '0,"No error"'


def test_unknown_fault_names_are_refused(sim):
    assert set(FAULTS) == set(sim.faults.known)
    with pytest.raises(ValueError, match="unknown fault"):
        sim.faults.arm("no_replies")


def test_no_reply_loses_exactly_one_reply(sim, client):
    client.sock.settimeout(0.3)
    sim.faults.arm("no_reply")
    client.send(":interlock:close 1")  # settings do not consume a reply fault
    client.send("*IDN?")
    with pytest.raises(TimeoutError):
        client.read_line()
    assert client.ask(":interlock? 1") == "1"


def test_late_reply_arrives_after_the_delay(sim, client):
    sim.faults.arm("late_reply", delay_s=0.5)
    client.sock.settimeout(0.1)
    client.send("*IDN?")
    with pytest.raises(TimeoutError):
        client.read_line()  # not there yet ...
    client.sock.settimeout(3.0)
    assert client.read_line().startswith("ACUTRONIC")  # ... but it does come
    assert sim.faults.history == ["late_reply"]


def test_garbled_reply_is_terminated_but_unreadable(sim, client):
    sim.faults.arm("garbled_reply")
    reply = client.ask(":read:rate? 1")
    assert reply.startswith("\x15")
    with pytest.raises(ValueError):
        float(reply)
    assert float(client.ask(":read:rate? 1")) == 0.0


def test_drop_connection_resets_the_client_and_new_connections_work(sim, client):
    sim.faults.arm("drop_connection")
    client.send("*IDN?")
    with pytest.raises((ConnectionError, OSError)):
        client.read_line()
    fresh = LineClient(sim.host, sim.port)
    try:
        assert fresh.ask("*IDN?").startswith("ACUTRONIC")
    finally:
        fresh.close()


def test_error_reply_refuses_the_next_setting_command(sim, client):
    client.command(":interlock:close 1")
    sim.faults.arm("error_reply", code=-240, message="Hardware error")
    assert client.ask("*IDN?").startswith("ACUTRONIC")  # queries do not consume it
    assert client.ask(":mode:rate 1;:syst:err?") == '-240,"Hardware error;simulated fault"'
    assert client.ask(":mode? 1") == "OFF"  # the refused command did not run
    assert client.ask(":mode:rate 1;:syst:err?") == '0,"No error"'


def test_interlock_fault_stops_a_spinning_table_until_cleared_and_closed(sim, client, clock):
    client.command(":interlock:close 1;:mode:rate 1;:demand:rate 1, 100")
    clock.advance_to(10.0)
    sim.faults.arm("interlock_open", count=None)
    assert client.ask(":interlock? 1") == "0"
    clock.advance_to(11.0)  # stopping at 50 deg/s^2
    assert float(client.ask(":read:rate? 1")) == pytest.approx(50.0)
    assert client.ask(":interlock:close 1;:syst:err?").startswith("201,")
    assert client.ask(":mode:rate 1;:syst:err?").startswith("201,")
    clock.advance_to(20.0)
    assert float(client.ask(":read:rate? 1")) == 0.0
    sim.faults.clear("interlock_open")
    assert client.ask(":interlock? 1") == "0"  # still open until closed by command
    assert client.ask(":interlock:close 1;:mode:rate 1;:syst:err?") == '0,"No error"'


def test_stop_is_idempotent_and_closes_clients(physics):
    server = SimulatedAcutrol(physics).start()
    c = LineClient(server.host, server.port)
    assert c.ask("*IDN?")
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
    c = LineClient(server.host, server.port)
    c.send("*IDN?")
    time.sleep(0.1)
    stopper = threading.Thread(target=server.stop)
    stopper.start()
    stopper.join(timeout=5.0)
    assert not stopper.is_alive()  # the 30 s delay did not hold the server
    c.close()
