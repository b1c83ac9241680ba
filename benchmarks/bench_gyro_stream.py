"""Gyro datagram throughput: decode + CRC over big buffers, and end to end through a pty.

Run:  .venv/bin/python benchmarks/bench_gyro_stream.py [--frames 5000000] [--e2e-frames 1000000]

Targets: decode + CRC >= 5 M frames/s on a clean buffer; SimulatedGyroPort
(SimClock) -> pty -> Stim300Gyro >= 200 000 frames/s. Figures are best of
``--repeat`` runs (the machine is shared; the best run is the least disturbed).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gyrocal.instruments.gyro.datagram import FrameDecoder, encode_frame_array
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.sim.gyro_pty import SimulatedGyroPort
from gyrocal.models.clock import SimClock


def make_buffer(
    n_frames: int, with_temperature: bool, corrupt_fraction: float, garbage_runs: int = 0, seed: int = 1
) -> bytes:
    """Frames, a fraction of them corrupted, plus ``garbage_runs`` random 1..40-byte insertions.

    Garbage breaks the frame alignment, which forces the decoder's general
    (every identifier byte is a candidate) path.
    """
    rng = np.random.default_rng(seed)
    rate = rng.normal(0.0, 50.0, (n_frames, 3))
    temp = 25.0 + rng.normal(0.0, 0.1, (n_frames, 3)) if with_temperature else None
    frames = encode_frame_array(rate, np.arange(n_frames), temp_c=temp, latency_us=250)
    if corrupt_fraction:
        bad = rng.choice(n_frames, int(corrupt_fraction * n_frames), replace=False)
        frames[bad, 2] ^= 0xFF
    if not garbage_runs:
        return frames.tobytes()
    cuts = np.sort(rng.choice(n_frames, garbage_runs, replace=False))
    pieces = []
    for rows in np.split(frames, cuts):
        pieces.append(rows.tobytes())
        pieces.append(rng.integers(0, 256, int(rng.integers(1, 41)), dtype=np.uint8).tobytes())
    return b"".join(pieces)


def bench_decode(
    n_frames: int, with_temperature: bool, corrupt_fraction: float, repeat: int, garbage_runs: int = 0
):
    data = make_buffer(n_frames, with_temperature, corrupt_fraction, garbage_runs)
    best_s, out = float("inf"), None
    for _ in range(repeat):
        decoder = FrameDecoder(with_temperature=with_temperature)
        t0 = time.perf_counter()
        out = decoder.feed(data)
        best_s = min(best_s, time.perf_counter() - t0)
    return n_frames / best_s, len(out), out.crc_errors, out.lost_frames


def bench_encode(n_frames: int, repeat: int) -> float:
    rate = np.random.default_rng(2).normal(0.0, 50.0, (n_frames, 3))
    best_s = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        encode_frame_array(rate, np.arange(n_frames))
        best_s = min(best_s, time.perf_counter() - t0)
    return n_frames / best_s


def bench_end_to_end(n_frames: int, block_samples: int, with_temperature: bool):
    clock = SimClock()
    fs_hz = 2000.0

    def source(t_s):
        return 10.0 * np.sin(2 * np.pi * 0.5 * t_s), 25.0 + 0.0 * t_s

    with SimulatedGyroPort(source, clock, sample_rate_hz=fs_hz, with_temperature=with_temperature,
                           block_frames=512) as sim:
        gyro = Stim300Gyro(sim.port_name, sample_rate_hz=fs_hz, with_temperature=with_temperature,
                           timeout_s=10.0)
        try:
            gyro.flush()
            got = lost = crc = 0
            t0 = time.perf_counter()
            while got < n_frames:
                want = min(block_samples, n_frames - got)
                clock.elapse_reading(want / fs_hz)      # as the orchestrator does on simulated time
                block = gyro.read_samples(want)
                got += len(block)
                lost += block.lost_frames
                crc += block.crc_errors
            elapsed_s = time.perf_counter() - t0
        finally:
            gyro.close()
    return got / elapsed_s, clock.now_s(), lost, crc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5_000_000)
    parser.add_argument("--e2e-frames", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()

    print(f"{'case':52s} {'frames/s':>14s}  notes")
    print("-" * 90)
    rate = bench_encode(args.frames, args.repeat)
    print(f"{'encode 0x90 frames':52s} {rate:14,.0f}")
    for with_temp in (False, True):
        for corrupt in (0.0, 0.01):
            rate, n_ok, crc, lost = bench_decode(args.frames, with_temp, corrupt, args.repeat)
            kind = "0x94" if with_temp else "0x90"
            name = f"decode+CRC {kind}, {args.frames:,} frames, {corrupt:.0%} corrupt"
            print(f"{name:52s} {rate:14,.0f}  good={n_ok:,} crc_errors={crc:,} lost={lost:,}")
    rate, n_ok, crc, lost = bench_decode(args.frames, False, 0.01, args.repeat, garbage_runs=1000)
    name = "decode+CRC 0x90, 1% corrupt + 1000 garbage runs"
    print(f"{name:52s} {rate:14,.0f}  good={n_ok:,} crc_errors={crc:,} lost={lost:,} (general path)")
    for with_temp in (False, True):
        rate, sim_s, lost, crc = bench_end_to_end(args.e2e_frames, 20_000, with_temp)
        kind = "0x94" if with_temp else "0x90"
        name = f"end to end pty {kind}, {args.e2e_frames:,} frames @ 2 kHz"
        print(f"{name:52s} {rate:14,.0f}  sim time {sim_s:,.1f} s, lost={lost}, crc_errors={crc}")


if __name__ == "__main__":
    main()
