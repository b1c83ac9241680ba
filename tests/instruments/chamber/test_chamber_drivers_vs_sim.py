"""Both chamber drivers against their simulators over real loopback TCP, faults included."""

import pytest

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentProtocolError,
    InstrumentTimeout,
)
from gyrocal.instruments.interfaces import Chamber
from gyrocal.instruments.sim.chamber_server import SimulatedWatlowF4

pytestmark = pytest.mark.timeout(20)


def test_driver_satisfies_the_chamber_protocol(rig):
    _, driver, _ = rig
    assert isinstance(driver, Chamber)


def test_identify_reports_model_and_serial(rig):
    sim, driver, _ = rig
    identity = driver.identify()
    assert identity.role == "chamber"
    assert identity.address == sim.address
    assert "F4" in identity.description
    expected_serial = "12-3456" if isinstance(sim, SimulatedWatlowF4) else "1234567"
    assert expected_serial in identity.description


def test_setpoint_round_trip_and_pv_follows_the_physics(rig, clock, physics):
    _, driver, _ = rig
    assert driver.read_temperature_c() == pytest.approx(22.0, abs=0.05)
    driver.set_setpoint_c(60.0)
    assert physics.setpoint_c == pytest.approx(60.0, abs=1e-5)
    assert driver.read_setpoint_c() == pytest.approx(60.0, abs=1e-5)
    clock.advance_to(300.0)   # mid-ramp: 5 °C/min for 5 min
    assert driver.read_temperature_c() == pytest.approx(physics.true_temperature_c(), abs=0.051)
    clock.advance_to(3 * 3600.0)
    status = driver.read_status()
    assert status.temperature_c == pytest.approx(60.0, abs=0.05)
    assert status.setpoint_c == pytest.approx(60.0, abs=1e-5)
    assert status.alarm is False


def test_negative_setpoints_survive_the_encoding(rig, physics):
    _, driver, _ = rig
    driver.set_setpoint_c(-40.0)
    assert physics.setpoint_c == pytest.approx(-40.0, abs=1e-5)
    assert driver.read_setpoint_c() == pytest.approx(-40.0, abs=1e-5)


def test_out_of_range_setpoint_is_refused_with_the_modbus_exception(rig, physics):
    _, driver, retries = rig
    with pytest.raises(InstrumentProtocolError) as info:
        driver.set_setpoint_c(500.0)
    error = info.value
    assert "Modbus exception 3 (illegal data value)" in error.detail
    assert error.instrument == driver.name and "set point" in error.command
    assert error.reply                   # the raw exception frame is shown
    assert not error.transient and retries == []
    assert physics.setpoint_c == 22.0


def test_no_reply_once_is_retried_after_a_reconnect(rig):
    sim, driver, retries = rig
    sim.faults.arm("no_reply", count=1)
    assert driver.read_setpoint_c() == pytest.approx(22.0, abs=1e-5)
    assert len(retries) == 1 and isinstance(retries[0], InstrumentTimeout)


def test_persistent_no_reply_ends_in_a_timeout_naming_instrument_and_command(rig):
    sim, driver, retries = rig
    driver.identify()            # connected: an F4T has read its display units (1328) by now
    sim.faults.arm("no_reply", count=None)
    with pytest.raises(InstrumentTimeout) as info:
        driver.read_temperature_c()
    text = str(info.value)
    assert driver.name in text
    assert "read holding register" in text and "process value" in text
    assert ("100" in text) if "F4T" not in driver.name else ("2820-2821" in text)
    assert sim.faults.history.count("no_reply") == 3     # three attempts, then give up
    assert len(retries) == 2


def test_a_late_reply_within_the_timeout_is_accepted(rig):
    sim, driver, retries = rig
    sim.faults.arm("late_reply", count=1, delay_s=0.05)
    assert driver.read_setpoint_c() == pytest.approx(22.0, abs=1e-5)
    assert retries == []


def test_a_reply_later_than_the_timeout_is_never_taken_for_the_next_answer(rig, physics):
    sim, driver, retries = rig
    driver.set_setpoint_c(55.0)
    sim.faults.arm("late_reply", count=1, delay_s=0.6)
    assert driver.read_setpoint_c() == pytest.approx(55.0, abs=1e-5)
    assert len(retries) == 1 and isinstance(retries[0], InstrumentTimeout)
    # the stale setpoint reply went to the abandoned connection: PV reads stay PV
    assert driver.read_temperature_c() == pytest.approx(physics.true_temperature_c(), abs=0.051)
    assert driver.read_setpoint_c() == pytest.approx(55.0, abs=1e-5)


def test_modbus_exception_is_reported_with_its_code_and_meaning(rig):
    sim, driver, retries = rig
    sim.faults.arm("modbus_exception", count=None, code=4)
    with pytest.raises(InstrumentProtocolError) as info:
        driver.read_temperature_c()
    assert "Modbus exception 4 (server device failure)" in str(info.value)
    assert retries == []                  # a device failure is not retried blindly


def test_device_busy_is_transient_and_retried(rig):
    sim, driver, retries = rig
    sim.faults.arm("modbus_exception", count=1, code=6)
    assert driver.read_setpoint_c() == pytest.approx(22.0, abs=1e-5)
    assert len(retries) == 1 and "server device busy" in str(retries[0])


def test_dropped_connection_reconnects_and_succeeds(rig):
    sim, driver, retries = rig
    assert driver.read_setpoint_c() == pytest.approx(22.0, abs=1e-5)   # connection open
    sim.faults.arm("drop_connection", count=1)
    driver.set_setpoint_c(30.0)
    assert driver.read_setpoint_c() == pytest.approx(30.0, abs=1e-5)
    assert len(retries) == 1
    assert isinstance(retries[0], InstrumentConnectionError | InstrumentTimeout)


def test_alarm_fault_is_visible_in_the_status(rig):
    sim, driver, _ = rig
    assert driver.read_status().alarm is False
    sim.faults.arm("alarm", count=None)
    status = driver.read_status()
    assert status.alarm is True and "alarm" in status.detail
    sim.faults.clear("alarm")
    assert driver.read_status().alarm is False


def test_process_alarm_from_the_physics_reaches_the_status(rig, clock, physics):
    _, driver, _ = rig
    physics.alarm_high_c = 40.0
    driver.set_setpoint_c(60.0)
    clock.advance_to(2 * 3600.0)
    status = driver.read_status()
    assert status.alarm is True and status.detail


def test_never_reaches_setpoint_makes_the_pv_stall(rig, clock, physics):
    sim, driver, _ = rig
    sim.faults.arm("never_reaches_setpoint", count=None)
    driver.set_setpoint_c(100.0)
    clock.advance_to(8 * 3600.0)
    stalled_c = driver.read_temperature_c()
    clock.advance_to(10 * 3600.0)
    assert driver.read_temperature_c() == pytest.approx(stalled_c, abs=0.05)
    assert stalled_c < 100.0 - 20.0
    assert driver.read_setpoint_c() == pytest.approx(100.0, abs=1e-5)
    sim.faults.clear("never_reaches_setpoint")
    driver.read_setpoint_c()                   # next request lifts the fault
    clock.advance_to(14 * 3600.0)
    assert driver.read_temperature_c() == pytest.approx(100.0, abs=0.05)


def test_a_stopped_server_gives_a_connection_error_after_the_retries(rig):
    sim, driver, retries = rig
    sim.stop()
    with pytest.raises(InstrumentConnectionError) as info:
        driver.read_temperature_c()
    assert driver.name in str(info.value)
    assert len(retries) == 2
