"""The simulated gyro on a pty, read by a second, independent reader.

This reader uses plain ``os.read`` on the slave device and a minimal
``struct`` decoder with a bit-by-bit CRC written here from the documented
layout, so a shared bug in the project's encoder and decoder cannot hide.
"""

import os
import select
import struct
import threading
import time

import numpy as np
import pytest
from crc_reference import bitwise_crc32_mpeg2 as bitwise_crc

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.gyro_pty import FAULTS, SimulatedGyroPort
from gyrocal.models.clock import RealClock, SimClock

pytestmark = pytest.mark.timeout(30)

FS_HZ = 1000.0
LSB = 2.0**-14


def source(t_s):
    return 100.0 * np.sin(2 * np.pi * 1.5 * t_s) - 3.0, 25.0 + 10.0 * np.cos(t_s)




def read_raw(port_name: str, n_bytes: int, timeout_s: float = 5.0) -> bytes:
    fd = os.open(port_name, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        data = bytearray()
        deadline = time.monotonic() + timeout_s
        while len(data) < n_bytes and time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready:
                data += os.read(fd, n_bytes - len(data))
        return bytes(data)
    finally:
        os.close(fd)


def minimal_decode_0x94(data: bytes):
    """Find the first valid 0x94 datagram, then unpack consecutive ones with struct.

    Layout and CRC rule from the STIM300 datasheet: 25 bytes (identifier,
    3 × 24-bit rates, status, 3 × 16-bit temperatures, temperature status,
    counter, 2-byte latency, CRC-32 over the first 21 bytes + 3 dummy zeros).
    """
    def crc_ok(i):
        return bitwise_crc(data[i : i + 21] + bytes(3)) == struct.unpack(">I", data[i + 21 : i + 25])[0]

    start = next(i for i in range(len(data) - 25) if data[i] == 0x94 and crc_ok(i))
    frames = []
    for i in range(start, len(data) - 24, 25):
        ident, rx, ry, rz, status, tx, ty, tz, tstatus, counter, latency, crc = struct.unpack(
            ">B3s3s3sBhhhBBHI", data[i : i + 25])
        assert ident == 0x94, f"lost sync at byte {i}"
        assert crc_ok(i), f"bad CRC at byte {i}"
        raw = int.from_bytes(rx, "big", signed=True)
        assert int.from_bytes(ry, "big", signed=True) == int.from_bytes(rz, "big", signed=True) == 0
        assert tx == ty == tz and tstatus == 0
        frames.append((raw, status, tx, counter, latency))
    return frames


def test_simulator_speaks_the_documented_layout_to_an_independent_reader():
    clock = SimClock()
    with SimulatedGyroPort(source, clock, sample_rate_hz=FS_HZ, with_temperature=True,
                           lsb=LSB, block_frames=50) as sim:
        clock.elapse_reading(600 / FS_HZ)
        data = read_raw(sim.port_name, 25 * 600)
    frames = minimal_decode_0x94(data)
    assert len(frames) >= 590
    counters = np.array([f[3] for f in frames])
    steps = np.diff(counters.astype(int)) % 256
    # TS1524 §7.5.2.2.18 (p. 55): the counter counts the internal 2000 Hz samples,
    # so at 1000 Hz it steps by 2 per datagram.
    assert np.all(steps == 2), "counter must step by 2000 / fs = 2 (mod 256)"
    # Recover the frame number: the first frame is k0 with 2 k0 = counter (mod 256).
    raw = np.array([f[0] for f in frames])
    temp = np.array([f[2] for f in frames])
    assert counters[0] % 2 == 0
    candidates = [k0 for k0 in range(counters[0] // 2, 12000, 128)
                  if np.array_equal(raw, np.rint(source((k0 + np.arange(len(frames))) / FS_HZ)[0] / LSB))]
    assert len(candidates) == 1, "the rates must match the source on the t_k = k / fs grid"
    t_s = (candidates[0] + np.arange(len(frames))) / FS_HZ
    assert np.array_equal(temp, np.rint(source(t_s)[1] * 256))
    assert {f[1] for f in frames} == {0} and {f[4] for f in frames} == {250}


def test_simulated_time_moves_only_with_the_controller():
    """Only the controller moves a SimClock; a running gyro neither moves it nor sends ahead."""
    clock = SimClock()
    with SimulatedGyroPort(source, clock, sample_rate_hz=FS_HZ, lsb=LSB, block_frames=32) as sim:
        time.sleep(0.2)
        assert clock.now_s() == 0.0 and sim.next_frame == 0
        assert read_raw(sim.port_name, 18, timeout_s=0.2) == b""
        assert sim.running
    assert not sim.running


def test_idle_time_leaves_only_the_last_frames_and_reading_time_every_frame():
    """While nobody reads, only the last 0.1 s is in the UART; while read, every frame."""
    clock = SimClock()
    with SimulatedGyroPort(source, clock, sample_rate_hz=FS_HZ, lsb=LSB, block_frames=32) as sim:
        clock.sleep(30.0)                              # e.g. a soak: nobody reads
        clock.elapse_reading(200 / FS_HZ)              # then a read of 200 frames
        data = read_raw(sim.port_name, 18 * 300, timeout_s=2)
    assert len(data) == 18 * 300, "100 tail frames + 200 read frames, nothing more"
    counters = np.frombuffer(data, np.uint8)[11::18].astype(int)   # 0x90: counter at offset 11
    k_expected = np.arange(30000 - 100, 30200)
    assert np.array_equal(counters, (k_expected * round(2000 / FS_HZ)) % 256)   # TS1524 §7.5.2.2.18
    raw = np.array([int.from_bytes(data[i + 1:i + 4], "big", signed=True)
                    for i in range(0, len(data), 18)])
    assert np.array_equal(raw, np.rint(source(k_expected / FS_HZ)[0] / LSB))


def test_real_clock_stream_starts_at_the_current_time_and_is_paced():
    clock = RealClock()
    fs_hz = 100.0
    time.sleep(0.1)                                     # the session clock has been running
    with SimulatedGyroPort(source, clock, sample_rate_hz=fs_hz, lsb=LSB, block_frames=5) as sim:
        got = read_raw(sim.port_name, 18 * 15, timeout_s=5)
        # Written blocks never lie in the future of the clock.
        assert sim.next_frame / fs_hz <= clock.now_s() + 5 / fs_hz
    assert len(got) == 18 * 15
    counters = list(got[11::18])     # 0x90: counter at offset 11
    assert got[0] == 0x90
    # TS1524 §7.5.2.2.18: 2000 Hz internal samples counted, so 20 per datagram at 100 Hz;
    # the first frame k0 (k0 < 64 here) has 20 k0 = counter (mod 256).
    k0 = next(k for k in range(64) if (20 * k) % 256 == counters[0])
    assert k0 >= 10, "frames from before the gyro started must not be replayed"
    assert np.all(np.diff(counters) % 256 == 20)


def test_unknown_fault_names_are_refused():
    injector = FaultInjector(FAULTS, owner="simulated gyro")
    with pytest.raises(ValueError, match="simulated gyro: unknown fault 'corupt_frames'"):
        injector.arm("corupt_frames")


def test_source_without_temperature_is_reported_as_the_writer_error():
    ended = threading.Event()

    def rate_only(t_s):
        ended.set()
        return np.zeros_like(t_s), None

    clock = SimClock()
    with SimulatedGyroPort(rate_only, clock, with_temperature=True) as sim:
        clock.elapse_reading(0.01)
        ended.wait(2)
        for _ in range(100):
            if not sim.running:
                break
            time.sleep(0.01)
        assert isinstance(sim.error, ValueError)
        assert "no temperature" in str(sim.error)


def test_frames_sampled_before_the_readers_flush_never_arrive_after_it():
    """Issue 28: a writer that falls behind (starved of CPU on a loaded host) must not hand
    the reader, after its flush, frames sampled before it. On a real serial port those frames
    would have waited in the input queue and gone with the flush. The source's rate is the
    frame's own sample time (deg/s = s), so each frame says when it was sampled; the source
    stalls 0.4 s on one frame and the reader flushes 0.15 s into the stall."""
    import termios

    fs_hz = 100.0
    clock = RealClock()
    stall, stalling, stalled_at = threading.Event(), threading.Event(), []

    def time_source(t_s):
        if stall.is_set():
            stall.clear()
            stalled_at.append(float(t_s[0]))
            stalling.set()
            time.sleep(0.4)
        return np.asarray(t_s, dtype=float).copy(), None

    with SimulatedGyroPort(time_source, clock, sample_rate_hz=fs_hz, lsb=LSB) as sim:
        fd = os.open(sim.port_name, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            time.sleep(0.1)
            stall.set()
            assert stalling.wait(2.0)
            time.sleep(0.15)
            flushed_s = clock.now_s()
            termios.tcflush(fd, termios.TCIFLUSH)
            data = bytearray()
            deadline = time.monotonic() + 3.0
            while len(data) < 18 * 6 and time.monotonic() < deadline:
                ready, _, _ = select.select([fd], [], [], 0.1)
                if ready:
                    data += os.read(fd, 18 * 6 - len(data))
        finally:
            os.close(fd)
    start = next(i for i in range(len(data) - 18) if data[i] == 0x90 == data[i + 18])
    # 0x90 (TS1524 Table 5-20): identifier, then the X rate as 24-bit two's complement
    first_sampled_s = int.from_bytes(data[start + 1 : start + 4], "big", signed=True) * LSB
    [stalled_s] = stalled_at
    assert stalled_s < flushed_s - 0.1
    assert first_sampled_s >= flushed_s - 1.0 / fs_hz, (stalled_s, flushed_s, first_sampled_s)


def test_on_simulated_time_nothing_made_before_a_readers_flush_reaches_it_without_a_wait():
    """A driver's flush waits for in-flight bytes through ``Clock.transport_wait``, which
    on a SimClock returns at once: the simulated port itself drops, at the controller's next
    advance, every frame it made before the reader's flush. Here that is a lost frame's
    make-up block of 20,000 frames (360 kB, more than a pty holds, so most of it is still in
    the writer's queue at the flush: no wall-time wait would have let it through); after the
    flush the reader gets exactly the frames of the next read span, none of the block."""
    from gyrocal.instruments.gyro.stim300 import Stim300Gyro

    clock = SimClock()
    faults = FaultInjector(FAULTS, owner="simulated gyro")
    with SimulatedGyroPort(source, clock, sample_rate_hz=FS_HZ, lsb=LSB, faults=faults,
                           block_frames=20_000) as sim:
        gyro = Stim300Gyro(sim.port_name, sample_rate_hz=FS_HZ, lsb=LSB, timeout_s=5.0,
                           transport_wait=clock.transport_wait)
        try:
            faults.arm("lose_frames", 1)
            clock.elapse_reading(1000 / FS_HZ)      # 1,000 frames, one lost: made up by a block
            assert len(gyro.read_samples(1000)) == 1000
            assert sim.next_frame == 21_000
            gyro.flush()
            clock.elapse_reading(200 / FS_HZ)
            block = gyro.read_samples(200)
        finally:
            gyro.close()
    k = np.arange(21_000, 21_200)
    # TS1524 §7.5.2.2.18: the counter counts the 2000 Hz internal samples, 2 per frame at 1 kHz
    assert np.array_equal(np.asarray(block.counter), (2 * k) % 256)
    assert np.array_equal(np.asarray(block.rate), np.rint(source(k / FS_HZ)[0] / LSB) * LSB)
