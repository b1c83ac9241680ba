"""Stim300Gyro against the simulated gyro over a real pseudo-terminal.

The source is a ramp whose raw value equals the frame number k (rate = t_s
with lsb = 1/fs), so every decoded sample says exactly which frame it was and
the driver's counts can be compared with the truth.
"""

import os
import threading
import time
import tty

import numpy as np
import pytest
from stim300_bytes import hand_frame_94

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentProtocolError,
    InstrumentTimeout,
)
from gyrocal.instruments.gyro.datagram import RAW_FULL_SCALE, encode_frames
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.interfaces import GyroStream
from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.gyro_pty import FAULTS, SimulatedGyroPort
from gyrocal.models.clock import RealClock, SimClock

pytestmark = pytest.mark.timeout(30)

FS_HZ = 2000.0
LSB = 1.0 / FS_HZ          # rate = t_s  ->  raw = k


def ramp_source(t_s):
    return t_s.copy(), 20.0 + 0.5 * np.sin(t_s)


@pytest.fixture
def rig():
    """Factory: (sim, gyro) pairs that are always torn down."""
    made = []

    def make(clock, with_temperature=False, faults=None, block_frames=64):
        sim = SimulatedGyroPort(
            ramp_source, clock, sample_rate_hz=FS_HZ, with_temperature=with_temperature,
            lsb=LSB, faults=faults, block_frames=block_frames,
        )
        sim.start()
        gyro = Stim300Gyro(sim.port_name, sample_rate_hz=FS_HZ, with_temperature=with_temperature,
                           lsb=LSB, timeout_s=5.0)
        made.append((sim, gyro))
        return sim, gyro

    yield make
    for sim, gyro in made:
        gyro.close()
        sim.stop()


def take(clock, gyro, n, timeout_s=5.0):
    """What the orchestrator does on simulated time: let n frames' time pass, read them."""
    clock.elapse_reading(n / FS_HZ)
    return gyro.read_samples(n, timeout_s=timeout_s)


def frame_numbers(block):
    k = np.rint(block.rate / LSB).astype(np.int64)
    assert np.array_equal(block.counter, (k % 256).astype(np.uint8)), "rate and counter disagree"
    return k


def test_driver_satisfies_the_gyro_stream_protocol(rig):
    sim, gyro = rig(SimClock())
    assert isinstance(gyro, GyroStream)
    identity = gyro.identify()
    assert identity.role == "gyro" and identity.driver == "stim300"
    assert identity.address == sim.port_name and "0x90" in identity.description


def test_sim_clock_stream_gives_the_frames_of_the_time_the_reader_lets_pass(rig):
    clock = SimClock()
    sim, gyro = rig(clock, with_temperature=True, block_frames=64)
    gyro.flush()
    blocks = [take(clock, gyro, 5000, timeout_s=10) for _ in range(4)]
    k = np.concatenate([frame_numbers(b) for b in blocks])
    assert np.array_equal(k, np.arange(20000)), "every frame of the elapsed time, in order"
    assert all(b.lost_frames == b.crc_errors == b.garbage_bytes == 0 for b in blocks)
    assert np.array_equal(np.concatenate([b.index for b in blocks]), np.arange(k.size))
    temp = np.concatenate([b.temperature_c for b in blocks])
    expected_temp = np.rint((20.0 + 0.5 * np.sin(k / FS_HZ)) * 256) / 256
    assert np.array_equal(temp, expected_temp)
    # Nobody but the reader moved simulated time: it is exactly where the reading ended.
    assert clock.now_s() == pytest.approx(20000 / FS_HZ, abs=1e-9)
    time.sleep(0.05)
    assert clock.now_s() == pytest.approx(20000 / FS_HZ, abs=1e-9)


def test_surplus_samples_carry_over_to_the_next_call(rig):
    clock = SimClock()
    sim, gyro = rig(clock)
    clock.elapse_reading(3008 / FS_HZ)
    first = gyro.read_samples(7)
    second = gyro.read_samples(3000)
    third = gyro.read_samples(1)
    k = np.concatenate([frame_numbers(b) for b in (first, second, third)])
    assert [len(first), len(second), len(third)] == [7, 3000, 1]
    assert np.array_equal(np.diff(k), np.ones(k.size - 1))
    assert np.concatenate([first.index, second.index, third.index]).tolist() == list(range(3008))


def test_flush_after_the_controller_waited_gives_fresh_frames(rig):
    clock = SimClock()
    sim, gyro = rig(clock)
    take(clock, gyro, 500)
    clock.sleep(10.0)                   # the orchestrator waiting for a chamber: nobody reads
    gyro.flush()
    block = take(clock, gyro, 3000)
    k = frame_numbers(block)
    assert block.index[0] == 0
    # The frames made while nobody read are gone; the first one read is the first
    # frame after the wait, and none is missing after it.
    assert np.array_equal(k, 500 + int(10.0 * FS_HZ) + np.arange(3000))


@pytest.mark.parametrize("n_faulty", [1, 5, 200])
def test_corrupt_frames_are_counted_and_never_returned(rig, n_faulty):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    k_before = frame_numbers(take(clock, gyro, 100))[-1]
    faults.arm("corrupt_frames", count=n_faulty)
    blocks = [take(clock, gyro, 1000) for _ in range(5)]
    k = np.concatenate([frame_numbers(b) for b in blocks])   # every sample is a true frame
    assert sim.injected["corrupt_frames"] == n_faulty
    assert sum(b.crc_errors for b in blocks) == n_faulty
    assert sum(b.lost_frames for b in blocks) == n_faulty == (k[-1] - k_before) - k.size
    assert sum(b.garbage_bytes for b in blocks) == 0


def test_lost_frames_are_counted_from_the_counter(rig):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    k_before = frame_numbers(take(clock, gyro, 100))[-1]
    faults.arm("lose_frames", count=7)
    blocks = [take(clock, gyro, 1000) for _ in range(5)]
    k = np.concatenate([frame_numbers(b) for b in blocks])
    assert sim.injected["lose_frames"] == 7
    assert sum(b.lost_frames for b in blocks) == 7 == (k[-1] - k_before) - k.size
    assert sum(b.crc_errors + b.garbage_bytes for b in blocks) == 0


def test_garbage_is_skipped_and_every_byte_accounted_for(rig):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    take(clock, gyro, 100)
    faults.arm("garbage", count=4, n_bytes=53)
    blocks = [take(clock, gyro, 1000) for _ in range(5)]
    k = np.concatenate([frame_numbers(b) for b in blocks])
    assert np.array_equal(np.diff(k), np.ones(k.size - 1)), "garbage must not cost a frame"
    assert sim.injected["garbage_bytes"] == 4 * 53
    # A random identifier byte followed by a frame length of garbage is a
    # "CRC error" span; either way every injected byte is accounted for.
    skipped = sum(b.garbage_bytes + 18 * b.crc_errors for b in blocks)   # 0x90 is 18 bytes
    assert skipped == 4 * 53
    assert sum(b.lost_frames for b in blocks) == 0


def test_saturated_frames_are_flagged_at_full_scale(rig):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    take(clock, gyro, 100)
    faults.arm("saturate", count=4)
    block = take(clock, gyro, 5000)
    flagged = block.flagged
    assert np.array_equal(flagged, (block.status & 0x10) != 0)      # datasheet bit 4: overload
    assert block.flagged_count == 4
    assert int(flagged.sum()) == 4 == sim.injected["saturate"]
    assert np.all(block.rate[flagged] == RAW_FULL_SCALE * LSB)
    k = np.rint(block.rate[~flagged] / LSB).astype(np.int64)
    assert np.array_equal(block.counter[~flagged], (k % 256).astype(np.uint8))
    assert block.lost_frames == 0 and block.crc_errors == 0


def test_stall_raises_a_clear_timeout_and_the_stream_resumes(rig):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    before = take(clock, gyro, 100)
    faults.arm("stall", count=None)
    with pytest.raises(InstrumentTimeout) as caught:
        take(clock, gyro, 2000, timeout_s=0.3)
    error = caught.value
    assert error.instrument == "gyro" and error.transient
    assert "read_samples(n=2000" in str(error)
    assert "of 2000 samples within 0.3 s" in str(error) and sim.port_name in str(error)
    faults.clear("stall")
    after = gyro.read_samples(2000, timeout_s=5)    # the frames of the time already let pass
    k_after = frame_numbers(after)
    assert np.array_equal(np.diff(k_after), np.ones(k_after.size - 1))
    # Samples decoded before the timeout were kept for this call, and nothing
    # was lost: a stalled SimClock gyro loses no frames.
    assert after.lost_frames == 0
    assert after.index[0] == before.index[-1] + 1
    assert k_after[0] == frame_numbers(before)[-1] + 1


def test_timed_stall_is_ridden_out_within_the_timeout(rig):
    faults = FaultInjector(FAULTS)
    clock = SimClock()
    sim, gyro = rig(clock, faults=faults)
    take(clock, gyro, 10)
    faults.arm("stall", count=1, duration_s=0.3)
    block = take(clock, gyro, 30000, timeout_s=10)
    k = frame_numbers(block)
    assert np.array_equal(np.diff(k), np.ones(k.size - 1))
    assert sim.injected["stalls"] == 1


def test_real_clock_paces_frames_and_never_sends_them_early(rig):
    clock = RealClock()
    sim, gyro = rig(clock, block_frames=20)
    for _ in range(3):
        block = gyro.read_samples(150, timeout_s=3)
        k = frame_numbers(block)
        assert np.array_equal(np.diff(k), np.ones(k.size - 1))
        # A frame is only written once the clock has reached its block's end.
        assert clock.now_s() >= (k[-1] + 1) / FS_HZ


def test_gyro_gone_is_a_connection_error(rig):
    clock = SimClock()
    sim, gyro = rig(clock)
    take(clock, gyro, 10)
    sim.stop()
    with pytest.raises((InstrumentConnectionError, InstrumentTimeout)) as caught:
        for _ in range(100):
            gyro.read_samples(5000, timeout_s=0.5)
    assert caught.value.instrument == "gyro"


def test_missing_port_is_a_connection_error_naming_the_port():
    with pytest.raises(InstrumentConnectionError, match="gyro-x: open /dev/nonexistent-gyro"):
        Stim300Gyro("/dev/nonexistent-gyro", name="gyro-x")


def test_pyserial_url_ports_work_too():
    """``loop://`` echoes what is written to it: the driver reads it like a line."""
    gyro = Stim300Gyro("loop://", lsb=LSB)
    try:
        rate = np.zeros((5, 3))
        rate[:, 0] = np.arange(5) * LSB
        gyro._serial.write(encode_frames(rate, np.arange(5), lsb=LSB))
        block = gyro.read_samples(5, timeout_s=1)
        assert np.rint(block.rate / LSB).tolist() == [0, 1, 2, 3, 4]
    finally:
        gyro.close()


@pytest.mark.parametrize(("axis", "column"), [("x", 0), ("y", 1), ("z", 2)])
def test_station_axis_selects_the_unit_under_test_and_all_three_are_kept(axis, column):
    """Datasheet-built 0x94 datagrams with CR LF; the driver hands over the chosen axis."""
    raw = [(100, -200, 300), (101, -201, 301), (102, -202, 302)]
    # frame 1: overload on y (datasheet status bits 4 and 1)
    status = [0x00, 0x12, 0x00]
    data = b"".join(hand_frame_94(r, s, (6400, 6656, 6912), 0, k, 500) + b"\r\n"
                    for k, (r, s) in enumerate(zip(raw, status, strict=True)))
    gyro = Stim300Gyro("loop://", lsb=LSB, with_temperature=True, axis=axis, crlf=True)
    try:
        gyro._serial.write(data)
        block = gyro.read_samples(3, timeout_s=1)
    finally:
        gyro.close()
    assert np.rint(block.rate_xyz / LSB).astype(int).tolist() == [list(r) for r in raw]
    assert np.rint(block.rate / LSB).astype(int).tolist() == [r[column] for r in raw]
    assert block.temperature_c.tolist() == [[25.0, 26.0, 27.0][column]] * 3
    assert block.flagged.tolist() == [False, axis == "y", False]
    assert block.crc_errors == 0 and block.garbage_bytes == 0


def test_a_line_with_no_datagram_of_any_type_is_a_fault_not_a_silent_timeout():
    """Bytes on a pty with no identifier byte of Table 5-21 (a wrong baud rate looks like this)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    gyro = Stim300Gyro(os.ttyname(slave), lsb=LSB, timeout_s=5)
    writer = threading.Thread(target=os.write, args=(master, bytes(range(0x20, 0x80)) * 700),
                              daemon=True)                  # 67,200 bytes
    writer.start()
    try:
        with pytest.raises(InstrumentProtocolError, match="no datagram of any STIM300 normal-mode type"):
            gyro.read_samples(10)
    finally:
        gyro.close()
        os.close(master)
        os.close(slave)


def test_detect_reports_the_stream_and_keeps_its_samples():
    gyro = Stim300Gyro("loop://", lsb=LSB, sample_rate_hz=250.0, with_temperature=True)
    try:
        frames = [hand_frame_94((k, -k, 2 * k), 0, (6400, 6400, 6400), 0, (8 * k) % 256, 500)
                  for k in range(10)]                               # 250 Hz: counter step 8
        gyro._serial.write(b"".join(frames))
        survey = gyro.detect(timeout_s=1)
        assert (survey.layout.identifier, survey.counter_step, survey.sample_rate_hz) == (0x94, 8, 250.0)
        block = gyro.read_samples(10, timeout_s=1)
        assert np.rint(block.rate / LSB).astype(int).tolist() == list(range(10))
        assert block.lost_frames == 0
    finally:
        gyro.close()
