"""Who the unit is: ``N<CR>`` and ``I<CR>`` at connect, and its start-up datagrams.

TS1524 rev 31: Table 8-1, §8.1 Table 8-3 and §8.2 Table 8-4 (p. 58): N and I,
upper case, then CR (Table 8-2), each answered by one datagram replacing the
next normal-mode datagram(s). §7.5.1 (p. 47): after a power-on the unit sends
its part number, serial number and configuration datagrams (the bias trim
offset one if configured), then enters Normal Mode; Table 5-2 Note 1 (p. 8):
the transmissions start with the part number datagram. The driver talks to
the simulated STIM300 over a real pty; the simulator's bytes come from its own
encoding of Tables 5-13 and 5-15 (checked against typed bytes in
test_special_datagrams.py).
"""

from __future__ import annotations

import os
import tty

import numpy as np
import pytest

from gyrocal.instruments.errors import InstrumentTimeout
from gyrocal.instruments.gyro.datagram_types import layout_of
from gyrocal.instruments.gyro.identity_query import PART_NUMBER_COMMAND, SERIAL_NUMBER_COMMAND
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.identity import reported_serial
from gyrocal.instruments.sim.gyro_frames import encode_sim_frames
from gyrocal.instruments.sim.gyro_pty import SimulatedGyroPort
from gyrocal.instruments.sim.stim_configuration import SimUnitConfiguration, configuration_datagram
from gyrocal.instruments.sim.stim_identity import (
    SIM_PART_NUMBER,
    part_number_datagram,
    serial_number_datagram,
)
from gyrocal.models.clock import SimClock

pytestmark = pytest.mark.timeout(60)

FS_HZ = 2000.0
LSB = 1.0 / FS_HZ          # rate = t_s  ->  raw = frame number
SERIAL = "N00000000004242"


def _source(sends_from_s: float | None):
    """A ramp; silent (no frame) before ``sends_from_s``, as a unit switched on then."""
    def source(t_s):
        rate = t_s.copy()
        if sends_from_s is not None:
            rate[t_s < sends_from_s - 1e-9] = np.nan
        return rate, 20.0 + 0.0 * t_s
    return source


@pytest.fixture
def rig():
    made = []

    def make(*, serial=SERIAL, sends_from_s=None):
        clock = SimClock()
        sim = SimulatedGyroPort(_source(sends_from_s), clock, sample_rate_hz=FS_HZ, lsb=LSB,
                                block_frames=64, datagram=0x90, unit_serial=serial)
        if sends_from_s is not None:
            sim.starts_from = lambda: sends_from_s
        sim.start()
        gyro = Stim300Gyro(sim.port_name, sample_rate_hz=FS_HZ, lsb=LSB, timeout_s=5.0,
                           datagram=0x90)
        made.append((sim, gyro))
        return clock, sim, gyro

    yield make
    for sim, gyro in made:
        gyro.close()
        sim.stop()


def test_the_commands_are_capital_n_and_i_then_cr():
    assert bytes([0x4E, 0x0D]) == PART_NUMBER_COMMAND      # Table 8-3
    assert bytes([0x49, 0x0D]) == SERIAL_NUMBER_COMMAND    # Table 8-4


def test_the_unit_says_its_part_number_and_serial_and_the_identity_carries_them(rig):
    clock, sim, gyro = rig()
    assert gyro.confirm_configuration(let_pass=clock.elapse_reading).confirmed   # C first
    answer = gyro.ask_identity(let_pass=clock.elapse_reading)
    assert sim.identity_answers == 2
    assert answer.part.part_number == SIM_PART_NUMBER and answer.part.revision == "G"
    assert answer.serial.serial == SERIAL and answer.confirmed
    description = gyro.identify().description
    assert f"unit part number {SIM_PART_NUMBER} rev G, serial {SERIAL}" in description
    assert "; configuration confirmed" in description     # the serial's text ends before it
    assert reported_serial(description) == SERIAL          # what the report and the locks read
    clock.elapse_reading(400 / FS_HZ)
    block = gyro.read_samples(400, timeout_s=5.0)
    k = np.rint(block.rate / LSB).astype(np.int64)
    # each question lets 100 frames pass; I's answer, the third, took frame 200's slot
    # (20 bytes, 0.22 ms at 921600 bit/s: one 2 kHz slot); the stream goes on right after it
    assert k[0] == 201 and np.array_equal(np.diff(k), np.ones(399))
    assert (block.lost_frames, block.crc_errors, block.garbage_bytes) == (0, 0, 0)


def test_a_unit_that_does_not_answer_i_is_not_confirmed_and_no_serial_is_read(rig):
    # the simulated unit answers I only with a serial Table 5-15 can carry (N and 14 digits)
    clock, sim, gyro = rig(serial="SIM-0001")
    answer = gyro.ask_identity(timeout_s=0.5, let_pass=clock.elapse_reading)
    assert answer.part is not None and answer.serial is None and not answer.confirmed
    description = gyro.identify().description
    assert "serial: not confirmed (no answer to I, TS1524 §8.2)" in description
    assert reported_serial(description) is None


def test_start_up_datagrams_after_a_power_on_are_cut_decoded_and_not_garbage(rig):
    # the unit starts sending 0.3 s into the clock (Table 5-2 Note 1: at most 0.3 s)
    clock, sim, gyro = rig(sends_from_s=0.3)
    clock.elapse_reading(0.5)
    block = gyro.read_samples(400, timeout_s=5.0)
    assert sim.start_ups == 1
    k = np.rint(block.rate / LSB).astype(np.int64)
    assert k[0] == 600                                     # the first normal-mode datagram
    assert (block.lost_frames, block.crc_errors, block.garbage_bytes) == (0, 0, 0)
    said = gyro.take_start_up().record()
    assert said["datagrams"] == ["part number", "serial number", "configuration"]
    assert (said["part_number"], said["revision"], said["serial"]) == (SIM_PART_NUMBER, "G", SERIAL)
    assert "2000 samples/s, datagram 0x90" in said["configuration"]
    assert gyro.take_start_up() is None                    # handed over once


def _frames(n: int) -> bytes:
    """``n`` 0x90 datagrams of the ramp, by the simulator's encoder (frame k says k)."""
    k = np.arange(n, dtype=np.int64)
    rate = np.zeros((n, 3))
    rate[:, 0] = k * LSB
    return encode_sim_frames(k, rate, None, layout=layout_of(0x90, False), lsb=LSB,
                             latency_us=250, sample_rate_hz=FS_HZ,
                             accelerometer_range_g=10).tobytes()


def test_start_up_datagrams_split_across_reads_and_after_line_noise_are_still_cut():
    """What a power-on puts on the line, written into a pty in pieces: 4090 bytes of noise,
    then the start-up datagrams (the first straddling the driver's 4 KiB look), then Normal
    Mode. The noise is garbage; the datagrams are not, however the reads cut them."""
    unit = SimUnitConfiguration(FS_HZ, False, False, False, False, False, 921600, 10)
    start_up = (part_number_datagram(SIM_PART_NUMBER, "G", False)
                + serial_number_datagram(SERIAL, False) + configuration_datagram(unit))
    # bytes below 0x8F: no identifier of any datagram (Tables 5-13 to 5-21) among them
    noise = np.random.default_rng(5).integers(0, 0x8F, 4090, dtype=np.uint8).tobytes()
    master, slave = os.openpty()
    tty.setraw(slave)
    gyro = Stim300Gyro(os.ttyname(slave), sample_rate_hz=FS_HZ, lsb=LSB, timeout_s=0.3,
                       datagram=0x90)
    try:
        os.write(master, noise + start_up[:12])          # the part number datagram, cut short
        with pytest.raises(InstrumentTimeout):
            gyro.read_samples(1, timeout_s=0.3)
        assert gyro.take_start_up() is None                # not whole yet: held, not garbage
        os.write(master, start_up[12:] + _frames(300))
        block = gyro.read_samples(300, timeout_s=5.0)
    finally:
        gyro.close()
        os.close(master)
        os.close(slave)
    assert block.garbage_bytes == len(noise) and (block.crc_errors, block.lost_frames) == (0, 0)
    assert np.array_equal(np.rint(block.rate / LSB), np.arange(300))
    said = gyro.take_start_up().record()
    assert said["datagrams"] == ["part number", "serial number", "configuration"]
    assert said["serial"] == SERIAL
