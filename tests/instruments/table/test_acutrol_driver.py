"""The ACUTROL3000 driver against the simulated table (TM-8004 framing) over real TCP through pyvisa-py."""

import math
import socket

import pytest

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentProtocolError,
    InstrumentSafetyError,
    InstrumentTimeout,
)
from gyrocal.instruments.interfaces import RateTable
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.table_server import SimulatedAcutrol
from gyrocal.instruments.table import acutrol_protocol as proto
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import SimClock
from gyrocal.models.table import MODE_OFF, MODE_RATE, TablePhysics

pytestmark = pytest.mark.timeout(30)

NOISE_DPS = 0.002
IDN = "ACUTRONIC,ACUTROL3000-SIM,SN123,3.0"


@pytest.fixture
def clock():
    return SimClock()


@pytest.fixture
def physics(clock):
    return TablePhysics(
        clock, max_rate_dps=600.0, max_accel_dps2=100.0, rate_noise_dps=NOISE_DPS, seed=3
    )


@pytest.fixture
def sim(physics):
    with SimulatedAcutrol(physics, idn=IDN) as server:
        yield server


@pytest.fixture
def retries():
    return []


@pytest.fixture
def table(sim, retries):
    driver = Acutrol3000Table(
        sim.resource,
        axis=1,
        timeout_s=0.3,
        retry=RetryPolicy(attempts=3, backoff_s=0.01),
        on_retry=lambda attempt, exc: retries.append(exc),
    )
    yield driver
    driver.close()


def spinning(table, rate_dps=100.0):
    table.close_interlock()
    table.set_rate_mode()
    table.set_rate_dps(rate_dps)


def test_driver_satisfies_the_rate_table_role_and_identifies(table, sim):
    assert isinstance(table, RateTable)
    identity = table.identify()
    assert identity.role == "table"
    assert identity.driver == "acutrol3000"
    assert identity.address == sim.resource
    assert identity.description == IDN


def test_ramp_then_readback_equals_the_demand_within_noise(table, clock, physics):
    assert table.interlock_closed() is False
    table.close_interlock()
    assert table.interlock_closed() is True
    table.set_rate_mode()
    assert physics.mode == MODE_RATE
    table.set_acceleration_limit_dps2(40.0)
    assert table.read_acceleration_limit_dps2() == 40.0
    table.set_rate_dps(-120.0)            # 3 s ramp, -180 deg
    clock.advance_to(1.5)
    assert table.read_rate_dps() == pytest.approx(-60.0, abs=5 * NOISE_DPS)
    clock.advance_to(10.0)                # then 7 s at -120: -840 deg; total -1020 deg
    readings = [table.read_rate_dps() for _ in range(20)]
    assert all(abs(r + 120.0) < 5 * NOISE_DPS for r in readings)
    assert len(set(readings)) > 1         # it is a noisy readback, not the demand echoed
    assert table.read_position_deg() == pytest.approx((-1020.0) % 360.0, abs=1e-5)
    status = table.read_status()
    assert status.rate_dps == pytest.approx(-120.0, abs=5 * NOISE_DPS)
    assert status.position_deg == pytest.approx(60.0, abs=1e-5)
    assert status.interlock_closed is True


def test_out_of_range_demand_is_refused_with_table_command_and_reply(table, physics):
    spinning(table, 10.0)
    with pytest.raises(InstrumentProtocolError) as caught:
        table.set_rate_dps(700.0)
    error = caught.value
    assert not error.transient
    assert error.instrument == "table"
    assert error.command == ":Demand:Rate 1,700.000000"
    assert error.reply.startswith("error 2 (Parameter out of range)")   # :Query:Error? 2
    assert "table: :Demand:Rate 1,700.000000" in str(error)
    assert physics.demand_dps == 10.0
    table.set_rate_dps(20.0)              # *ESR? was read (and so cleared): the next is clean
    assert physics.demand_dps == 20.0


def test_acceleration_limit_beyond_the_table_is_refused(table):
    with pytest.raises(InstrumentProtocolError, match=":Limit:Acceleration R,1,150") as caught:
        table.set_acceleration_limit_dps2(150.0)
    assert caught.value.reply.startswith("error 2 ") and not caught.value.transient
    with pytest.raises(ValueError, match="table"):
        table.set_acceleration_limit_dps2(math.nan)


def test_motion_with_the_interlock_open_is_a_safety_error(table):
    with pytest.raises(InstrumentSafetyError) as caught:
        table.set_rate_mode()
    assert caught.value.command == ":Mode:Rate 1"
    assert caught.value.reply.startswith("error 3 (Interlock open)")
    assert "interlock open" in str(caught.value)


def test_opening_the_interlock_unpowers_the_drive_and_closing_it_allows_rate_mode(table, physics):
    # the drive-off half of a table_interference step: `:interlock:open N` (the spelling of
    # the session start, docs/protocol-elements.md), read back open, then closed again
    table.close_interlock()
    table.set_rate_mode()
    table.open_interlock()
    assert not table.interlock_closed() and not physics.interlock_closed
    with pytest.raises(InstrumentSafetyError):
        table.set_rate_mode()
    table.close_interlock()
    table.set_rate_mode()
    assert table.interlock_closed()


def test_stop_demands_zero_then_servo_off(table, clock, physics):
    spinning(table, 100.0)
    clock.advance_to(5.0)
    table.stop()
    assert physics.mode == MODE_OFF
    assert physics.demand_dps == 0.0
    clock.advance_to(6.01)                # 100 deg/s at 100 deg/s^2: at rest after 1 s
    assert table.read_rate_dps() == pytest.approx(0.0, abs=5 * NOISE_DPS)
    table.stop()                          # stopping a stopped table is fine


def test_a_lost_reply_is_retried_and_reported(table, sim, retries):
    sim.faults.arm("no_reply")
    assert table.read_rate_dps() == pytest.approx(0.0, abs=5 * NOISE_DPS)
    assert len(retries) == 1 and isinstance(retries[0], InstrumentTimeout)
    assert retries[0].command == ":Read:Rate? 1"


def test_a_silent_table_times_out_naming_table_and_command(table, sim):
    sim.faults.arm("no_reply", count=None)
    with pytest.raises(InstrumentTimeout) as caught:
        table.read_position_deg()
    assert str(caught.value).startswith("table: :Read:Position? 1: no reply within 0.3 s")
    assert sim.faults.history.count("no_reply") == 3   # every attempt of the policy was made


def test_a_late_reply_is_not_mistaken_for_the_next_answer(table, sim, retries, physics):
    spinning(table, 0.0)
    sim.faults.arm("late_reply", delay_s=0.6)
    assert table.identify().description == IDN          # attempt 1 timed out, attempt 2 answered
    assert isinstance(retries[0], InstrumentTimeout)
    # The late IDN reply went to the abandoned socket; these replies are the right ones.
    assert table.interlock_closed() is True
    assert table.read_rate_dps() == pytest.approx(0.0, abs=5 * NOISE_DPS)


@pytest.fixture
def patient_table(sim, retries):
    """As ``table``, with a 2 s reply timeout: where what is asserted is not a timeout, a loaded
    host (load 7 with a disk writer) must not turn a reconnect after garbage into one."""
    driver = Acutrol3000Table(sim.resource, axis=1, timeout_s=2.0,
                              retry=RetryPolicy(attempts=3, backoff_s=0.01),
                              on_retry=lambda attempt, exc: retries.append(exc))
    yield driver
    driver.close()


def test_a_garbled_reply_is_retried_then_reported_as_unreadable(patient_table, sim, retries):
    table = patient_table
    sim.faults.arm("garbled_reply")
    assert table.interlock_closed() is False
    assert isinstance(retries[0], InstrumentProtocolError) and retries[0].transient
    sim.faults.arm("garbled_reply", count=None)
    with pytest.raises(InstrumentProtocolError) as caught:
        table.read_rate_dps()
    assert caught.value.command == ":Read:Rate? 1"
    assert "\x15" in caught.value.reply
    assert "unreadable reply" in str(caught.value)


def test_a_garbled_acknowledgement_repeats_the_idempotent_setting(table, sim, physics):
    table.close_interlock()
    table.set_rate_mode()
    sim.faults.arm("garbled_reply")
    table.set_rate_dps(42.0)
    assert physics.demand_dps == 42.0


def test_a_dropped_connection_reconnects_on_retry(table, sim, retries):
    assert table.identify().description == IDN   # a session is open
    sim.faults.arm("drop_connection")
    assert table.interlock_closed() is False
    assert len(retries) == 1 and isinstance(retries[0], InstrumentConnectionError)
    assert sim.faults.history == ["drop_connection"]


def test_a_table_that_keeps_dropping_the_line_is_a_connection_error(table, sim):
    sim.faults.arm("drop_connection", count=None)
    with pytest.raises(InstrumentConnectionError) as caught:
        table.identify()
    assert caught.value.instrument == "table"
    assert caught.value.transient


def test_an_execution_error_is_attempted_again_per_the_retries(table, sim, retries, physics):
    """Issue 9: a refusal that is not a bad message (*ESR? bit 2 clear) may pass: retried, journaled."""
    table.close_interlock()
    sim.faults.arm("error_reply")
    table.set_rate_mode()
    assert len(retries) == 1
    assert retries[0].reply.startswith("error 5 (Execution error)")
    assert retries[0].command == ":Mode:Rate 1"
    assert physics.mode == MODE_RATE


def test_a_command_error_is_a_refusal_not_retried(table, sim, retries, physics):
    """*ESR? bit 2, a bad device-dependent message (TM-8004 Table 1 p. 19): the same bytes
    would fail again."""
    table.close_interlock()
    sim.faults.arm("error_reply", code=2, bad_message=True)
    with pytest.raises(InstrumentProtocolError) as caught:
        table.set_rate_mode()
    assert caught.value.reply.startswith("error 2 (Parameter out of range)")
    assert caught.value.command == ":Mode:Rate 1"
    assert not caught.value.transient and retries == []
    assert physics.mode == MODE_OFF


def test_a_refusal_that_persists_ends_after_the_retries(table, sim, retries, physics):
    table.close_interlock()
    sim.faults.arm("error_reply", count=None)
    with pytest.raises(InstrumentProtocolError) as caught:
        table.set_rate_mode()
    assert caught.value.transient and len(retries) == 2      # 3 attempts in all
    assert physics.mode == MODE_OFF
    sim.faults.clear("error_reply")


def test_interlock_fault_stops_the_table_and_refuses_motion_until_cleared(table, sim, clock):
    spinning(table, 200.0)
    clock.advance_to(10.0)
    sim.faults.arm("interlock_open", count=None)
    status = table.read_status()
    assert status.interlock_closed is False
    clock.advance_to(11.0)
    assert table.read_rate_dps() == pytest.approx(100.0, abs=5 * NOISE_DPS)   # braking at 100
    with pytest.raises(InstrumentSafetyError):
        table.set_rate_dps(50.0)
    with pytest.raises(InstrumentSafetyError):
        table.close_interlock()
    table.stop()                                   # the safe state is always reachable
    clock.advance_to(13.0)
    assert table.read_rate_dps() == pytest.approx(0.0, abs=5 * NOISE_DPS)
    sim.faults.clear("interlock_open")
    spinning(table, 30.0)
    clock.advance_to(20.0)
    assert table.read_rate_dps() == pytest.approx(30.0, abs=5 * NOISE_DPS)


def test_nobody_listening_is_a_connection_error_naming_the_resource():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    resource = f"TCPIP0::127.0.0.1::{port}::SOCKET"
    driver = Acutrol3000Table(resource, timeout_s=0.2, retry=RetryPolicy(2, backoff_s=0.01))
    with pytest.raises(InstrumentConnectionError) as caught:
        driver.identify()
    assert caught.value.instrument == "table"
    assert resource in str(caught.value)
    driver.close()


@pytest.mark.parametrize(
    "resource", ["TCPIP0::127.0.0.1::notaport::SOCKET", "not a resource", "TCPIP0::127.0.0.1::SOCKET"]
)
def test_a_malformed_resource_is_refused_at_construction(resource):
    with pytest.raises(ValueError, match="invalid VISA resource"):
        Acutrol3000Table(resource, name="table")


def test_close_is_idempotent_and_a_closed_driver_refuses_commands(table):
    table.identify()
    table.close()
    table.close()
    with pytest.raises(InstrumentError, match="closed"):
        table.read_rate_dps()


def test_synthesis_through_the_driver_turns_the_sinusoid_the_readback_traces(table, clock, physics):
    """set_oscillator then set_synthesis_mode (TM-8004 §4.3.4, §4.7.6) move the simulated
    table: 0.1 deg peak at 5 Hz, phase 0 -> rate π cos(10π t) deg/s (peak 0.1·2π·5 = π)."""
    table.close_interlock()
    table.set_oscillator(0.1, 5.0, 0.0)
    table.set_synthesis_mode()
    assert table.read_mode() is proto.TableMode.SYNTHESIS
    start_s = clock.now_s()
    for dt_s in (0.0, 0.025, 0.05, 0.1, 0.13):
        clock.advance_to(start_s + dt_s)
        expected = math.pi * math.cos(10.0 * math.pi * dt_s)
        assert table.read_rate_dps() == pytest.approx(expected, abs=5 * NOISE_DPS)
    table.stop()
    clock.advance_to(start_s + 5.0)
    assert physics.rate_dps() == 0.0
