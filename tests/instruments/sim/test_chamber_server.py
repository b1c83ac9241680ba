"""The simulated chambers seen by clients that share no code with the drivers.

F4: a plain socket sending hand-built RTU frames. F4T: a raw pymodbus client,
with the float decoding written out here with ``struct`` (low word first).
Addresses are written literally, so a wrong entry in the shared register map
is caught here even though driver and simulator agree with each other.
"""

import socket
import struct

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.framer.rtu import FramerRTU

from gyrocal.instruments.sim.chamber_server import FAULTS, SimulatedWatlowF4, SimulatedWatlowF4T
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import SimClock

pytestmark = pytest.mark.timeout(20)


@pytest.fixture
def clock():
    return SimClock()


@pytest.fixture
def physics(clock):
    return ChamberPhysics(clock, ambient_c=22.0, tau_s=300.0, noise_c=0.0, seed=1)


@pytest.fixture
def f4(physics):
    with SimulatedWatlowF4(physics) as sim:
        yield sim


@pytest.fixture
def f4t(physics):
    with SimulatedWatlowF4T(physics) as sim:
        yield sim


def rtu_socket(sim):
    host, port = sim.address.removeprefix("socket://").split(":")
    sock = socket.create_connection((host, int(port)), timeout=2.0)
    return sock


def exchange(sock, request_hex, reply_len):
    sock.sendall(bytes.fromhex(request_hex))
    reply = b""
    while len(reply) < reply_len:
        chunk = sock.recv(reply_len - len(reply))
        if not chunk:
            break
        reply += chunk
    return reply


def crc_ok(frame):
    return FramerRTU.compute_CRC(frame[:-2]).to_bytes(2, "big") == frame[-2:]


def f4t_float(registers):
    return struct.unpack("<f", struct.pack("<HH", *registers))[0]


def test_f4_serves_pv_in_register_100_as_signed_tenths(f4, clock, physics):
    with rtu_socket(f4) as sock:
        assert exchange(sock, "01 03 00 64 00 01 C5 D5", 7) == bytes.fromhex("01 03 02 00 DC B9 DD")  # 22.0
        physics.set_setpoint(-40.0)
        clock.advance_to(6 * 3600.0)
        reply = exchange(sock, "01 03 00 64 00 01 C5 D5", 7)
    assert crc_ok(reply) and reply[:3] == bytes.fromhex("01 03 02")
    assert struct.unpack(">h", reply[3:5])[0] == -400


def test_f4_setpoint_write_to_register_300_reaches_the_physics(f4, physics):
    with rtu_socket(f4) as sock:
        frame = "01 06 01 2C 02 58 49 65"                       # 300 := 600 (60.0 °C)
        assert exchange(sock, frame, 8) == bytes.fromhex(frame)
        assert physics.setpoint_c == 60.0
        reply = exchange(sock, "01 03 01 2C 00 01 44 3F", 7)
        assert reply == bytes.fromhex("01 03 02 02 58 B8 DE")
        # out of range (2000.0 °C = 20000 = 0x4E20) is refused with exception 3
        request = bytes.fromhex("01 06 01 2C 4E 20")
        request += FramerRTU.compute_CRC(request).to_bytes(2, "big")
        reply = exchange(sock, request.hex(), 5)
    assert reply[:3] == bytes.fromhex("01 86 03") and crc_ok(reply)
    assert physics.setpoint_c == 60.0


def test_f4_identity_run_state_and_limit_input_registers(f4):
    """200: run state (0 constant, 2 profile running; Espec watlowf4.py), never an alarm;
    the alarm is digital input 1, active when its status (201) equals its condition (1061 = 1,
    high; F4P manual pp. 9.4-9.5): healthy 201 = 0, tripped 201 = 1."""
    with rtu_socket(f4) as sock:
        reply = exchange(sock, "01 03 00 00 00 03 05 CB", 11)
        assert crc_ok(reply) and struct.unpack(">3H", reply[3:9])[0] == 5270
        assert exchange(sock, "01 03 00 C8 00 01 05 F4", 7) == bytes.fromhex("01 03 02 00 00 B8 44")
        assert exchange(sock, "01 03 00 C9 00 01 54 34", 7) == bytes.fromhex("01 03 02 00 00 B8 44")
        assert exchange(sock, "01 03 04 25 00 01 94 F1", 7) == bytes.fromhex("01 03 02 00 01 79 84")
        f4.faults.arm("alarm", count=None)
        assert exchange(sock, "01 03 00 C8 00 01 05 F4", 7) == bytes.fromhex("01 03 02 00 00 B8 44")
        assert exchange(sock, "01 03 00 C9 00 01 54 34", 7) == bytes.fromhex("01 03 02 00 01 79 84")
        f4.faults.arm("profile_running", count=None)
        reply = exchange(sock, "01 03 00 C8 00 01 05 F4", 7)
    assert reply == bytes.fromhex("01 03 02 00 02 39 85")


def test_f4_undeclared_register_is_an_illegal_address(f4):
    with rtu_socket(f4) as sock:
        request = bytes.fromhex("01 03 00 96 00 01")            # register 150: not served
        request += FramerRTU.compute_CRC(request).to_bytes(2, "big")
        assert exchange(sock, request.hex(), 5) == bytes.fromhex("01 83 02 C0 F1")


def test_f4t_serves_documented_registers_low_word_first(f4t, clock, physics):
    client = ModbusTcpClient("127.0.0.1", port=f4t.bound_port, timeout=2, retries=0)
    try:
        # as shipped, Display Units (1328) is F (30) and temperatures are °F (F4T guide p. 225)
        assert client.read_holding_registers(1328, count=1, device_id=1).registers == [30]
        pv = client.read_holding_registers(2820, count=2, device_id=1)
        assert f4t_float(pv.registers) == pytest.approx(22.0 * 1.8 + 32.0)   # 71.6 °F
        assert not client.write_register(1328, 15, device_id=1).isError()  # front panel: C
        pv = client.read_holding_registers(2820, count=2, device_id=1)
        assert f4t_float(pv.registers) == pytest.approx(22.0)
        low, high = struct.unpack("<HH", struct.pack("<f", 45.5))
        assert not client.write_registers(2782, [low, high], device_id=1).isError()
        assert physics.setpoint_c == 45.5
        clock.advance_to(4 * 3600.0)
        pv = client.read_holding_registers(2820, count=2, device_id=1)
        assert f4t_float(pv.registers) == pytest.approx(45.5, abs=1e-4)
        part = client.read_holding_registers(16, count=15, device_id=1).registers
        assert "".join(chr(r) for r in part if r).startswith("F4T")
        assert client.read_holding_registers(90, count=1, device_id=1).registers == [138]
        assert client.read_holding_registers(1356, count=1, device_id=1).registers == [61]
        f4t.faults.arm("alarm", count=None, state=8)
        assert client.read_holding_registers(1356, count=1, device_id=1).registers == [8]
        # PV is read-only
        assert client.write_registers(2820, [0, 0], device_id=1).isError()
    finally:
        client.close()


def test_no_reply_swallows_one_answer_and_the_next_request_is_served(f4):
    f4.faults.arm("no_reply", count=1)
    with rtu_socket(f4) as sock:
        sock.settimeout(0.3)
        sock.sendall(bytes.fromhex("01 03 00 64 00 01 C5 D5"))
        with pytest.raises(TimeoutError):
            sock.recv(16)
        sock.settimeout(2.0)
        assert exchange(sock, "01 03 00 64 00 01 C5 D5", 7) == bytes.fromhex("01 03 02 00 DC B9 DD")
    assert f4.faults.history == ["no_reply"]


def test_late_reply_arrives_after_the_delay(f4):
    f4.faults.arm("late_reply", count=1, delay_s=0.5)
    with rtu_socket(f4) as sock:
        sock.settimeout(0.1)
        sock.sendall(bytes.fromhex("01 03 00 64 00 01 C5 D5"))
        with pytest.raises(TimeoutError):
            sock.recv(16)                                   # not yet...
        sock.settimeout(3.0)
        assert exchange(sock, "", 7) == bytes.fromhex("01 03 02 00 DC B9 DD")   # ...but it comes


def test_drop_connection_closes_the_socket_without_a_reply(f4t):
    f4t.faults.arm("drop_connection", count=1)
    with socket.create_connection(("127.0.0.1", f4t.bound_port), timeout=2.0) as sock:
        sock.sendall(bytes.fromhex("00 01 00 00 00 06 01 03 0B 04 00 02"))
        assert sock.recv(16) == b""                          # orderly close, nothing sent
    with socket.create_connection(("127.0.0.1", f4t.bound_port), timeout=2.0) as sock:
        sock.sendall(bytes.fromhex("00 02 00 00 00 06 01 03 0B 04 00 02"))
        assert sock.recv(16)[:9] == bytes.fromhex("00 02 00 00 00 07 01 03 04")


def test_modbus_exception_fault_uses_the_requested_code(f4t):
    f4t.faults.arm("modbus_exception", count=1, code=6)
    with socket.create_connection(("127.0.0.1", f4t.bound_port), timeout=2.0) as sock:
        sock.sendall(bytes.fromhex("00 01 00 00 00 06 01 03 0B 04 00 02"))
        assert sock.recv(16) == bytes.fromhex("00 01 00 00 00 03 01 83 06")


def test_fault_names_are_declared_and_typos_are_refused(physics):
    assert set(FAULTS) == {
        "no_reply", "late_reply", "modbus_exception", "drop_connection", "never_reaches_setpoint", "alarm",
        "profile_running",
    }
    sim = SimulatedWatlowF4(physics)
    with pytest.raises(ValueError, match="unknown fault"):
        sim.faults.arm("no_replies")
    with pytest.raises(ValueError, match="does not know"):
        SimulatedWatlowF4(physics, faults=FaultInjector(("no_reply",)))


def test_start_and_stop_are_idempotent_and_free_the_port(physics):
    sim = SimulatedWatlowF4T(physics)
    sim.stop()                                # never started: no-op
    sim.start()
    assert sim.start() is sim                 # already running: no-op
    port = sim.bound_port
    other = SimulatedWatlowF4T(physics).start()
    try:
        assert other.bound_port != port
    finally:
        other.stop()
    sim.stop()
    sim.stop()
    with pytest.raises(RuntimeError, match="not running"):
        _ = sim.address
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=1.0).close()


def test_a_busy_port_is_reported(physics, f4t):
    clash = SimulatedWatlowF4T(physics, port=f4t.bound_port)
    with pytest.raises(RuntimeError, match="could not listen"):
        clash.start()
