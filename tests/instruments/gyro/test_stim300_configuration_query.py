"""Asking the unit for its configuration at connect: ``C<CR>`` (TS1524 §8.3, Table 8-5, p. 59).

The driver talks to the simulated STIM300 through a real pty; the simulator's
answer is built by its own encoding of Table 5-16 (instruments/sim/
stim_configuration.py), never by the driver's decoder. A replayed capture is
one-way, as a unit that does not answer: no fault, "not confirmed".
The judging of an answer is also checked on bytes typed from Table 5-16
(bytes 0–6 p. 31, 7–13 p. 32, 14–27 p. 33).
"""

from __future__ import annotations

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc
from ubc_captures import SLOW

from gyrocal.instruments.errors import InstrumentProtocolError
from gyrocal.instruments.gyro.capture import read_capture
from gyrocal.instruments.gyro.configuration import GyroOutputUnit, decode_configuration
from gyrocal.instruments.gyro.configuration_query import (
    COMMAND,
    NOT_CONFIRMED,
    Declared,
    mismatches,
)
from gyrocal.instruments.gyro.datagram_types import layout_of
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.gyro_pty import SimulatedGyroPort
from gyrocal.instruments.sim.replay_pty import ReplayGyroPort
from gyrocal.models.clock import RealClock, SimClock

pytestmark = pytest.mark.timeout(60)

FS_HZ = 2000.0
LSB = 1.0 / FS_HZ          # rate = t_s  ->  raw = frame number


def ramp_source(t_s):
    return t_s.copy(), 20.0 + 0.0 * t_s


@pytest.fixture
def rig():
    made = []

    def make(clock, *, baudrate=921600, gyro_output_code=0, datagram=0x90, sim_range_g=10,
             declared_range_g=10):
        sim = SimulatedGyroPort(ramp_source, clock, sample_rate_hz=FS_HZ, lsb=LSB,
                                block_frames=64, datagram=datagram, baudrate=baudrate,
                                gyro_output_code=gyro_output_code,
                                accelerometer_range_g=sim_range_g).start()
        gyro = Stim300Gyro(sim.port_name, sample_rate_hz=FS_HZ, lsb=LSB, timeout_s=5.0,
                           baudrate=baudrate, datagram=datagram,
                           accelerometer_range_g=declared_range_g)
        made.append((sim, gyro))
        return sim, gyro

    yield make
    for sim, gyro in made:
        gyro.close()
        sim.stop()


def test_the_command_is_capital_c_then_cr():
    assert bytes([0x43, 0x0D]) == COMMAND          # Table 8-1 (upper case), Table 8-2 (CR 0x0D)


@pytest.mark.parametrize(("baudrate", "replaced"), [(921600, 1), (374400, 2)])
def test_on_simulated_time_the_answer_replaces_the_next_datagrams_and_no_frame_is_lost(
        rig, baudrate, replaced):
    """26 bytes at 10 bits a character: 0.28 ms at 921600 bit/s (one 2 kHz slot), 0.69 ms at
    374400 (two). The stream starts afresh after the answer: no lost frame, no garbage."""
    clock = SimClock()
    sim, gyro = rig(clock, baudrate=baudrate)
    first = sim.next_frame
    answer = gyro.confirm_configuration(let_pass=clock.elapse_reading)
    assert answer.confirmed and sim.configuration_answers == 1
    config = answer.configuration
    assert config.gyro_output_unit is GyroOutputUnit.ANGULAR_RATE
    assert (config.sample_rate_hz, config.datagram, config.crlf) == (2000.0, 0x90, False)
    assert config.bit_rate == baudrate
    assert "angular rate [°/s]" in answer.describe()
    clock.elapse_reading(500 / FS_HZ)
    block = gyro.read_samples(500, timeout_s=5.0)
    k = np.rint(block.rate / LSB).astype(np.int64)
    assert k[0] == first + replaced                  # the replaced slots are not in the stream
    assert np.array_equal(np.diff(k), np.ones(499))
    assert (block.lost_frames, block.crc_errors, block.garbage_bytes) == (0, 0, 0)


def test_on_a_real_clock_the_answer_comes_within_the_bound(rig):
    sim, gyro = rig(RealClock(1.0))
    answer = gyro.confirm_configuration(timeout_s=2.0)
    assert answer.confirmed and answer.replaced_frames in (None, 1)
    block = gyro.read_samples(200, timeout_s=5.0)
    assert (block.lost_frames, block.crc_errors, block.garbage_bytes) == (0, 0, 0)


def test_a_unit_set_to_incremental_angle_is_a_fault_naming_both_and_the_table(rig):
    clock = SimClock()
    _, gyro = rig(clock, gyro_output_code=0b0001)           # Table 5-16 byte 5: incremental angle
    with pytest.raises(InstrumentProtocolError) as error:
        gyro.confirm_configuration(let_pass=clock.elapse_reading)
    text = str(error.value)
    assert "gyro output unit is incremental angle [°]" in text
    assert "gyrocal reads angular rate [°/s]" in text and "TS1524 Table 5-16 byte 5" in text


def test_an_accelerometer_range_other_than_declared_is_a_fault(rig):
    clock = SimClock()
    _, gyro = rig(clock, datagram=0x93, sim_range_g=30, declared_range_g=10)
    with pytest.raises(InstrumentProtocolError, match=r"accelerometer range is ±30/30/30 g on "
                       r"x/y/z \(TS1524 Table 5-16 bytes 17–18\); the station declares ±10 g"):
        gyro.confirm_configuration(let_pass=clock.elapse_reading)


def test_a_one_way_replay_is_not_confirmed_and_its_stream_is_kept_whole():
    data = read_capture(SLOW)                              # 0x93 with CR LF at 125 Hz
    replay = ReplayGyroPort(data, RealClock(4.0), loop=False)
    gyro = Stim300Gyro(replay.port_name, sample_rate_hz=125, datagram=0x93, crlf=True,
                       accelerometer_range_g=30, timeout_s=10)
    with replay:
        try:
            answer = gyro.confirm_configuration(timeout_s=1.0)
            block = gyro.read_samples(50)
        finally:
            gyro.close()
    assert not answer.confirmed and answer.describe() == NOT_CONFIRMED
    assert NOT_CONFIRMED == "configuration not confirmed: no answer to C (TS1524 §8.3)"
    # the flush before the command lands mid-datagram: at most that partial datagram is garbage
    assert (block.crc_errors, block.lost_frames) == (0, 0)
    assert block.garbage_bytes < gyro.layout.length


def typed_answer(byte3: int, byte5: int, byte17: int = 0x00, byte18: int = 0x00) -> bytes:
    """Table 5-16 with the fields a test varies; the rest a plain unit (filters 262 Hz)."""
    body = bytes([0xBC, ord("A"), 3, byte3, 0b0010_0_00_0, byte5, 0x44, 0x40, 0x70, 0x44,
                  0x40, 0x70, 0x44, 0x40, 0x00, 0x00, 0x00, byte17, byte18, 0x00, 0x00, 0x00])
    return body + bitwise_crc(body + bytes(2)).to_bytes(4, "big")


DECLARED = Declared(sample_rate_hz=2000.0, layout=layout_of(0x94, False), axis=0,
                    accelerometer_range_g=10)


def test_a_unit_configured_as_declared_has_nothing_to_say():
    config = decode_configuration(typed_answer(0b100_0_1_0_0_0, 0b0_111_0000))   # 2000 Hz, temp
    assert mismatches(config, DECLARED) == []


@pytest.mark.parametrize(("byte3", "byte5", "expected"), [
    (0b011_0_1_0_0_0, 0b0_111_0000,
     "the unit is configured for 1000 samples/s (TS1524 Table 5-16 byte 3); the station declares 2000 Hz"),
    (0b101_0_1_0_0_0, 0b0_111_0000, "the unit is configured for external trigger"),
    (0b100_0_1_0_0_1, 0b0_111_0000,
     "datagram 0x94 (rate, temperature) with CR LF (TS1524 Table 5-16 byte 3, Table 5-21); "
     "the station declares 0x94 (rate, temperature)"),
    (0b100_0_0_0_1_0, 0b0_111_0000, "datagram 0x91 (rate, acceleration)"),
    (0b100_0_1_0_0_0, 0b0_111_0011, "gyro output unit is integrated angle [°]"),
    (0b100_0_1_0_0_0, 0b0_111_1000, "gyro output unit is angular rate [°/s], delayed"),
    (0b100_0_1_0_0_0, 0b0_011_0000,
     "the unit's gyro x axis is inactive (TS1524 Table 5-16 byte 5); the station declares the "
     "unit under test on the x axis"),
])
def test_each_contradiction_names_both_values_and_the_table(byte3, byte5, expected):
    found = mismatches(decode_configuration(typed_answer(byte3, byte5)), DECLARED)
    assert len(found) == 1 and expected in found[0]


def test_on_simulated_time_the_simulator_hears_a_command_before_its_time_passes(rig):
    """A slave write reaches the pty master through the kernel's flip-buffer work, in its
    own time; the dry-run engine waits for the simulated unit to take the command
    (``hear_command``) before it lets the command's time pass, so the answer's place in
    the stream never depends on the scheduler: the first datagram after the command,
    every time. Nothing written: nothing heard, within the bound."""
    for attempt in range(5):
        clock = SimClock()
        sim, gyro = rig(clock)
        assert sim.hear_command(timeout_s=0.02) is False
        heard = []

        def let_pass(span_s: float, sim=sim, clock=clock, heard=heard) -> None:
            heard.append(sim.hear_command())
            clock.elapse_reading(span_s)

        first = sim.next_frame
        assert gyro.confirm_configuration(let_pass=let_pass).confirmed and heard == [True]
        clock.elapse_reading(100 / FS_HZ)
        k = np.rint(gyro.read_samples(100, timeout_s=5.0).rate / LSB).astype(np.int64)
        assert k[0] == first + 1, attempt            # the answer took the command's next slot
