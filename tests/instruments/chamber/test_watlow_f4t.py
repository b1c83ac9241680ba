"""Watlow F4T driver: exact Modbus TCP byte pairs (MBAP header + PDU) on a real socket.

Float values are hand-worked IEEE-754 patterns sent low word first:
23.1 = 0x41B8CCCD -> ``CC CD 41 B8``; 25.0 = 0x41C80000 -> ``00 00 41 C8``;
77.0 = 0x429A0000 -> ``00 00 42 9A``.

The driver reads Display Units (register 1328 = 0x0530; F4T Setup and
Operations User's Guide 0600-0093-0000 Rev. F, chapter 6 appendix p. 225:
"F (30), C (15)", factory default F) before its first temperature, so each
conversation starts with that exchange.
"""


import pytest

from gyrocal.instruments.chamber.watlow_f4t import WatlowF4T, parse_tcp_address
from gyrocal.instruments.errors import InstrumentError, InstrumentProtocolError
from gyrocal.instruments.retry import RetryPolicy

pytestmark = pytest.mark.timeout(20)

NO_RETRY = RetryPolicy(attempts=1)
#: tid 1: read 1328, one register -> 15 (C) or 30 (F, the factory default)
UNITS_C = ("00 01 00 00 00 06 01 03 05 30 00 01", "00 01 00 00 00 05 01 03 02 00 0F")
UNITS_F = ("00 01 00 00 00 06 01 03 05 30 00 01", "00 01 00 00 00 05 01 03 02 00 1E")


def f4t_on(peer):
    return WatlowF4T(f"127.0.0.1:{peer.port}", timeout_s=0.5, retry=NO_RETRY)


def test_read_process_value_bytes(scripted_peer):
    # tid 2, protocol 0, length 6, unit 1, FC 03, address 2820 (0x0B04), count 2
    peer = scripted_peer([UNITS_C, ("00 02 00 00 00 06 01 03 0B 04 00 02",
                                    "00 02 00 00 00 07 01 03 04 CC CD 41 B8")])
    with f4t_on(peer) as f4t:
        assert f4t.read_temperature_c() == pytest.approx(23.1, abs=1e-6)
    assert peer.error is None


def test_write_setpoint_bytes(scripted_peer):
    # FC 16 to 2782 (0x0ADE), 2 registers, 4 bytes, low word first
    peer = scripted_peer([UNITS_C, (
        "00 02 00 00 00 0B 01 10 0A DE 00 02 04 00 00 41 C8",
        "00 02 00 00 00 06 01 10 0A DE 00 02",
    )])
    with f4t_on(peer) as f4t:
        f4t.set_setpoint_c(25.0)
    assert peer.error is None and len(peer.received) == 2


def test_a_factory_default_controller_speaks_fahrenheit_and_is_converted(scripted_peer):
    """Display Units F (30): 25 °C goes out as 77.0 °F, 77.0 °F comes back as 25 °C."""
    peer = scripted_peer([UNITS_F, (
        "00 02 00 00 00 0B 01 10 0A DE 00 02 04 00 00 42 9A",
        "00 02 00 00 00 06 01 10 0A DE 00 02",
    ), ("00 03 00 00 00 06 01 03 0B 04 00 02", "00 03 00 00 00 07 01 03 04 00 00 42 9A")])
    with f4t_on(peer) as f4t:
        f4t.set_setpoint_c(25.0)
        assert f4t.read_temperature_c() == pytest.approx(25.0, abs=1e-9)
    assert peer.error is None and len(peer.received) == 3


def test_unknown_display_units_are_a_fault_naming_the_register(scripted_peer):
    peer = scripted_peer([(UNITS_C[0], "00 01 00 00 00 05 01 03 02 00 07")])
    with f4t_on(peer) as f4t, pytest.raises(InstrumentError, match=r"register 1328 \(display units\) reads 7"):
        f4t.read_temperature_c()


def test_read_status_bytes(scripted_peer):
    peer = scripted_peer([
        ("00 01 00 00 00 06 01 03 05 4C 00 01", "00 01 00 00 00 05 01 03 02 00 07"),   # 1356: 7 alarm high
        ("00 02 00 00 00 06 01 03 00 5A 00 01", "00 02 00 00 00 05 01 03 02 00 8A"),   # 90: 138 OK
        # 16568 profile state (Espec watlowf4t.py get_status): 149 = 0x95 running
        ("00 03 00 00 00 06 01 03 40 B8 00 01", "00 03 00 00 00 05 01 03 02 00 95"),
        ("00 04 00 00 00 06 01 03 05 30 00 01", "00 04 00 00 00 05 01 03 02 00 0F"),   # 1328: C
        ("00 05 00 00 00 06 01 03 0B 04 00 02", "00 05 00 00 00 07 01 03 04 CC CD 41 B8"),
        ("00 06 00 00 00 06 01 03 0A DE 00 02", "00 06 00 00 00 07 01 03 04 00 00 41 C8"),
    ])
    with f4t_on(peer) as f4t:
        status = f4t.read_status()
    assert peer.error is None
    assert status.alarm is True and status.detail == "alarm 1 alarm high"
    assert status.profile_running is True and status.run_state == "profile running"
    assert status.temperature_c == pytest.approx(23.1, abs=1e-6) and status.setpoint_c == 25.0


def test_exception_reply_names_register_and_code(scripted_peer):
    peer = scripted_peer([UNITS_C, ("00 02 00 00 00 06 01 03 0A DE 00 02",
                                    "00 02 00 00 00 03 01 83 02")])
    with f4t_on(peer) as f4t, pytest.raises(InstrumentProtocolError) as info:
        f4t.read_setpoint_c()
    assert "read holding registers 2782-2783 (control loop 1 set point)" in str(info.value)
    assert "Modbus exception 2 (illegal data address)" in str(info.value)


@pytest.mark.parametrize(("text", "expected"), [("10.0.0.5:5020", ("10.0.0.5", 5020)), ("chamber3", ("chamber3", 502))])
def test_address_forms(text, expected):
    assert parse_tcp_address(text) == expected


@pytest.mark.parametrize("bad", ["host:", ":502", "host:99999", "host:abc"])
def test_bad_addresses_are_refused_clearly(bad):
    with pytest.raises(ValueError, match="host:port"):
        WatlowF4T(bad)


def test_word_order_high_first_is_a_station_setting(scripted_peer):
    """chamber.word_order: high_first swaps the words: 25.0 = 0x41C80000 -> ``41 C8 00 00``."""
    peer = scripted_peer([UNITS_C, (
        "00 02 00 00 00 0B 01 10 0A DE 00 02 04 41 C8 00 00",
        "00 02 00 00 00 06 01 10 0A DE 00 02",
    )])
    with WatlowF4T(f"127.0.0.1:{peer.port}", timeout_s=0.5, retry=NO_RETRY,
                   word_order="high_first") as f4t:
        f4t.set_setpoint_c(25.0)
    assert peer.error is None
