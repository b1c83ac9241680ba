"""Watlow F4 driver: exact RTU byte pairs on a real socket, then F4 specifics.

Request frames are the documented ones (register 100 read: ``01 03 00 64 00 01
C5 D5``); reply CRCs were computed with pymodbus' CRC, independent of this
project's code.
"""

import pytest

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4, f4_model_text
from gyrocal.instruments.errors import InstrumentProtocolError
from gyrocal.instruments.retry import RetryPolicy

pytestmark = pytest.mark.timeout(20)

NO_RETRY = RetryPolicy(attempts=1)


def f4_on(peer, **kwargs):
    return WatlowF4(f"socket://127.0.0.1:{peer.port}", timeout_s=0.5, retry=NO_RETRY, **kwargs)


def test_read_process_value_bytes(scripted_peer):
    peer = scripted_peer([("01 03 00 64 00 01 C5 D5", "01 03 02 00 E7 F8 0E")])   # 231 -> 23.1 °C
    with f4_on(peer) as f4:
        assert f4.read_temperature_c() == pytest.approx(23.1)
    assert peer.error is None and len(peer.received) == 1


def test_write_negative_setpoint_bytes(scripted_peer):
    frame = "01 06 01 2C FE 70 08 7B"                                # register 300 = -400 -> -40.0 °C
    peer = scripted_peer([(frame, frame)])                           # FC 06 replies with an echo
    with f4_on(peer) as f4:
        f4.set_setpoint_c(-40.0)
    assert peer.error is None and len(peer.received) == 1


@pytest.mark.parametrize(("status_reply", "tripped"), [
    ("01 03 02 00 01 79 84", True),      # register 201 = 1 (high) EQUALS condition 1: active
    ("01 03 02 00 00 B8 44", False),     # register 201 = 0 (low) differs: inactive, healthy
])
def test_read_status_bytes(scripted_peer, status_reply, tripped):
    """Register 200 is the run state (1: constant), not an alarm (Espec ChamberConnectLibrary
    watlowf4.py). The alarm is the limit controller's digital input 1, active when its
    status (201; F4P manual p. 9.5, 0 low / 1 high) equals its condition (1061; p. 9.4 and
    the Setup Page table p. 6.18: the state that triggers the input; p. 7.4)."""
    peer = scripted_peer([
        ("01 03 00 C8 00 01 05 F4", "01 03 02 00 01 79 84"),         # register 200: 1 constant
        ("01 03 00 C9 00 01 54 34", status_reply),                   # register 201: DI 1 status
        ("01 03 04 25 00 01 94 F1", "01 03 02 00 01 79 84"),         # register 1061: condition high
        ("01 03 00 64 00 01 C5 D5", "01 03 02 00 E7 F8 0E"),
        ("01 03 01 2C 00 01 44 3F", "01 03 02 02 58 B8 DE"),         # register 300: 600 -> 60.0 °C
    ])
    with f4_on(peer, limit_input=1) as f4:
        status = f4.read_status()
    assert peer.error is None
    assert (status.temperature_c, status.setpoint_c, status.alarm) == (pytest.approx(23.1), 60.0, tripped)
    assert status.detail == ("alarm: limit controller tripped (digital input 1)" if tripped else "")
    assert status.profile_running is False and status.run_state == "constant"


def test_register_200_is_the_run_state_never_an_alarm(scripted_peer):
    """The value 1 that the old driver read as "alarm 1 active" is a constant set point;
    2 is the controller running its own profile (preflight refuses to start)."""
    peer = scripted_peer([
        ("01 03 00 C8 00 01 05 F4", "01 03 02 00 02 39 85"),         # register 200: 2 running
        ("01 03 00 64 00 01 C5 D5", "01 03 02 00 E7 F8 0E"),
        ("01 03 01 2C 00 01 44 3F", "01 03 02 02 58 B8 DE"),
    ])
    with f4_on(peer) as f4:                                         # no limit input declared
        status = f4.read_status()
    assert peer.error is None
    assert status.alarm is False and status.profile_running is True
    assert status.run_state == "profile running"


def test_identify_bytes(scripted_peer):
    """Connect reads the model/serial (0-2), then input 1 decimals (606 = 1) and the
    temperature units (901 = 1, °C), as Espec's watlowf4.py reads them."""
    peer = scripted_peer([("01 03 00 00 00 03 05 CB", "01 03 06 14 96 00 0C 0D 80 AF 4F"),
                          ("01 03 02 5E 00 01 E4 60", "01 03 02 00 01 79 84"),
                          ("01 03 03 85 00 01 95 A7", "01 03 02 00 01 79 84")])
    with f4_on(peer) as f4:
        identity = f4.identify()
    assert identity.driver == "watlow_f4"
    assert identity.description == (
        "Watlow F4 (model register 5270), serial 12-3456, units °C (register 901), 1 decimal(s) "
        "(register 606), alarms NOT monitored (no chamber.limit_input in the station)")


def test_a_fahrenheit_f4_with_whole_degrees_is_converted(scripted_peer):
    """901 = 0 (°F) and 606 = 0 decimals: register 100 = 77 reads as 25 °C; 25 °C goes out as 77."""
    peer = scripted_peer([("01 03 00 00 00 03 05 CB", "01 03 06 14 96 00 0C 0D 80 AF 4F"),
                          ("01 03 02 5E 00 01 E4 60", "01 03 02 00 00 B8 44"),
                          ("01 03 03 85 00 01 95 A7", "01 03 02 00 00 B8 44"),
                          ("01 03 00 64 00 01 C5 D5", "01 03 02 00 4D 78 71"),
                          ("01 06 01 2C 00 4D 89 CA", "01 06 01 2C 00 4D 89 CA")])
    with f4_on(peer) as f4:
        assert "°F" in f4.identify().description
        assert f4.read_temperature_c() == pytest.approx(25.0)
        f4.set_setpoint_c(25.0)
    assert peer.error is None and len(peer.received) == 5


def test_modbus_exception_bytes_are_shown_in_the_error(scripted_peer):
    peer = scripted_peer([("01 03 00 64 00 01 C5 D5", "01 83 02 C0 F1")])
    with f4_on(peer, name="chamber A") as f4, pytest.raises(InstrumentProtocolError) as info:
        f4.read_temperature_c()
    text = str(info.value)
    assert text.startswith("chamber A: read holding register 100 (input 1 process value)")
    assert "Modbus exception 2 (illegal data address)" in text
    assert "01 83 02 c0 f1" in text


def test_identify_refuses_a_device_that_is_not_an_f4(scripted_peer):
    # model register 1234: some other controller answering at unit 1
    peer = scripted_peer([("01 03 00 00 00 03 05 CB", "01 03 06 04 D2 00 0C 0D 80 5D D0")])
    with f4_on(peer) as f4, pytest.raises(InstrumentProtocolError, match="a Series F4 reports 5270"):
        f4.identify()


def test_decimals_are_configurable():
    # 0 decimals: a register of 23 is 23 °C; 2 decimals: 2310 is 23.1 °C
    from gyrocal.instruments.chamber.watlow_f4 import F4_REGISTERS
    pv = F4_REGISTERS["process_value"]
    assert pv.decode([23], 0) == 23.0
    assert pv.decode([2310], 2) == pytest.approx(23.1)
    with pytest.raises(ValueError):
        WatlowF4("socket://127.0.0.1:1", decimals=5)


def test_model_register_decodes_to_its_name():
    assert f4_model_text(5270) == "F4"


def test_setpoint_with_more_decimals_than_the_controller_is_rounded(clock, physics):
    from gyrocal.instruments.sim.chamber_server import SimulatedWatlowF4

    with SimulatedWatlowF4(physics) as sim, WatlowF4(sim.address, timeout_s=0.5) as f4:
        f4.set_setpoint_c(23.14)
        assert f4.read_setpoint_c() == 23.1
        assert physics.setpoint_c == pytest.approx(23.1)


def test_serial_settings_are_checked():
    """Parity and stop bits come from the station (some public F4 scripts use 2 stop bits)."""
    with pytest.raises(ValueError, match="parity N/E/O and stop bits 1/2"):
        WatlowF4("/dev/ttyUSB0", parity="X")
    with pytest.raises(ValueError, match="parity N/E/O and stop bits 1/2"):
        WatlowF4("/dev/ttyUSB0", stop_bits=3)
