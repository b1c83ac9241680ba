"""The chamber drivers against a Modbus server that is not ours.

pymodbus's stock server with a plain datastore (no project code behind it)
holds the registers as the manuals and public drivers lay them out, written
here by hand: the F4T's Display Units (1328 = 30, °F, the factory default,
F4T guide p. 225) with loop 1 set point / process value (2782 / 2820, float32
low word first), alarm 1 state 1356 and device status 90; the F4's process
value / set point (100 / 300, tenths), run state 200 and its limit
controller's digital input (status 201, condition 1061; F4P manual pp.
9.4-9.5), and the F4T's profile state 16568 (Espec ChamberConnectLibrary).
The drivers must read temperatures, units, alarms and profile state
correctly and write set points in the controller's units.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest
from pymodbus.framer import FramerType

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4
from gyrocal.instruments.chamber.watlow_f4t import WatlowF4T
from gyrocal.instruments.errors import InstrumentProtocolError
from gyrocal.instruments.retry import RetryPolicy
from tests.support.modbus_stock_server import StockServer

pytestmark = pytest.mark.timeout(30)


def float_lwf(value: float) -> list[int]:
    """IEEE-754 single, low word first (struct, not the project's codec)."""
    high, low = struct.unpack(">HH", struct.pack(">f", value))
    return [low, high]


def from_float_lwf(words: list[int]) -> float:
    return struct.unpack(">f", struct.pack(">HH", words[1], words[0]))[0]


@pytest.fixture
def f4t_peer() -> Iterator[StockServer]:
    registers = {1328: 30, 90: 138, 1356: 61, 4: 7, 5: 0, 12: 4242, 13: 0, 16568: 61}
    registers.update(dict(zip((2782, 2783), float_lwf(77.0), strict=True)))     # 25 °C in °F
    registers.update(dict(zip((2820, 2821), float_lwf(71.6), strict=True)))     # 22 °C in °F
    registers.update({16 + i: ord(c) for i, c in enumerate("F4T1L0AA1A1AAA1")})
    with StockServer(registers, FramerType.SOCKET) as server:
        yield server


def test_f4t_driver_reads_units_temperatures_alarms_and_writes_in_fahrenheit(f4t_peer) -> None:
    with WatlowF4T(f"127.0.0.1:{f4t_peer.port}", timeout_s=1.0, retry=RetryPolicy(attempts=1)) as f4t:
        identity = f4t.identify()
        assert "part F4T1L0AA1A1AAA1" in identity.description and "°F" in identity.description
        assert f4t.read_temperature_c() == pytest.approx(22.0, abs=1e-4)
        assert f4t.read_setpoint_c() == pytest.approx(25.0, abs=1e-4)
        f4t.set_setpoint_c(-40.0)                                       # −40 °C = −40 °F
        assert from_float_lwf(f4t_peer.hr(2782, 2)) == pytest.approx(-40.0, abs=1e-4)
        f4t.set_setpoint_c(100.0)
        assert from_float_lwf(f4t_peer.hr(2782, 2)) == pytest.approx(212.0, abs=1e-3)
        assert f4t.read_status().alarm is False
        f4t_peer.set(1356, [7])
        status = f4t.read_status()
        assert status.alarm is True and "alarm 1" in status.detail


@pytest.fixture
def f4_peer() -> Iterator[StockServer]:
    """A healthy F4: the limit controller's contact on digital input 1 reads low (201 = 0)
    while the input is set to trigger on high (1061 = 1)."""
    registers = {0: 5270, 1: 12, 2: 3456, 100: 231, 300: 600, 200: 1, 201: 0, 1061: 1,
                 606: 1, 901: 1}                                    # tenths, °C
    with StockServer(registers, FramerType.RTU) as server:
        yield server


def test_f4_driver_reads_run_state_and_limit_input_not_register_200_as_alarm(f4_peer) -> None:
    with WatlowF4(f"socket://127.0.0.1:{f4_peer.port}", timeout_s=1.0,
                  retry=RetryPolicy(attempts=1), limit_input=1) as f4:
        assert "serial 12-3456" in f4.identify().description
        status = f4.read_status()
        assert status.temperature_c == pytest.approx(23.1) and status.setpoint_c == 60.0
        assert status.alarm is False and status.profile_running is False   # 200 = 1: constant
        f4.set_setpoint_c(-12.5)
        assert f4_peer.hr(300) == [(-125) & 0xFFFF]
        f4_peer.set(200, [3])                                               # profile paused
        assert f4.read_status().profile_running is True


# Watlow Series F4P user's manual, ch. 9 Modbus registers: digital input N status at
# 201 + 12 (N-1), 0 low / 1 high (p. 9.5); its condition at 1061 + 2 (N-1), 0 low / 1 high
# (p. 9.4; Setup Page table p. 6.18: the state that triggers the input). An input is active
# while its state equals its condition (features, p. 7.4). Espec's driver agrees since 13600df.
@pytest.mark.parametrize(("limit_input", "condition", "state", "tripped"), [
    (1, 1, 0, False),      # triggers on high, contact low: healthy
    (1, 1, 1, True),       # triggers on high, contact high: tripped
    (1, 0, 1, False),      # triggers on low, contact high: healthy
    (1, 0, 0, True),       # triggers on low, contact low: tripped
    (3, 1, 1, True),       # input 3: status 225, condition 1065
    (3, 1, 0, False),
])
def test_f4_limit_input_is_tripped_when_its_state_equals_its_condition(
        limit_input: int, condition: int, state: int, tripped: bool) -> None:
    status_register, condition_register = {1: (201, 1061), 3: (225, 1065)}[limit_input]
    # the other input's registers hold the opposite reading, so reading the wrong one fails
    decoys = {201: 1 - state, 1061: condition, 225: 1 - state, 1065: condition}
    registers = {0: 5270, 1: 12, 2: 3456, 100: 231, 300: 600, 200: 1, 606: 1, 901: 1, **decoys,
                 status_register: state, condition_register: condition}
    with StockServer(registers, FramerType.RTU) as peer, \
            WatlowF4(f"socket://127.0.0.1:{peer.port}", timeout_s=1.0,
                     retry=RetryPolicy(attempts=1), limit_input=limit_input) as f4:
        status = f4.read_status()
        assert status.alarm is tripped
        assert (f"digital input {limit_input}" in status.detail) is tripped
        peer.set(status_register, [1 - state])                           # the contact changes
        assert f4.read_status().alarm is not tripped


def test_f4_limit_input_outside_the_manuals_values_is_a_fault_naming_the_register() -> None:
    registers = {0: 5270, 200: 1, 201: 7, 1061: 1, 606: 1, 901: 1}
    with StockServer(registers, FramerType.RTU) as peer, \
            WatlowF4(f"socket://127.0.0.1:{peer.port}", timeout_s=1.0,
                     retry=RetryPolicy(attempts=1), limit_input=1) as f4, \
            pytest.raises(InstrumentProtocolError, match="holding register 201"):
        f4.read_status()


# Espec ChamberConnectLibrary watlowf4t.py get_status: register 16568, 149 running, 146 paused
# (its value table: 146 pause, 148 terminate, 149 running; 61 none).
@pytest.mark.parametrize(("profile_state", "running", "text"), [
    (149, True, "profile running"), (146, True, "profile paused"), (61, False, "constant"),
    (148, False, "constant"),
])
def test_f4t_profile_state_is_read_from_register_16568(
        f4t_peer, profile_state: int, running: bool, text: str) -> None:
    f4t_peer.set(16568, [profile_state])
    with WatlowF4T(f"127.0.0.1:{f4t_peer.port}", timeout_s=1.0, retry=RetryPolicy(attempts=1)) as f4t:
        status = f4t.read_status()
    assert (status.profile_running, status.run_state) == (running, text)
    assert status.alarm is False
