"""Generation speed of the gyro model simulator, in samples per second.

Plain script (speed is measured here, never asserted in tests):

    .venv/bin/python benchmarks/bench_model.py [--hours 1] [--block-s 60]

For each model and sample rate it streams ``--hours`` of data through
GyroSimulator in ``--block-s`` blocks (as the simulated instrument does) with
a table-rate and chamber-temperature profile, and prints samples/s, seconds
per hour of data and the peak traced memory.
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc
from pathlib import Path

import numpy as np

from gyrocal.models.gyro_model import EffectSpec, GyroModel, load_model
from gyrocal.models.gyro_sim import GyroSimulator

MODELS = Path(__file__).resolve().parents[1] / "gyro-models"


def nominal_fog_with_effects() -> GyroModel:
    model = load_model(MODELS / "nominal-fog.yaml")
    for name, params in [
        ("temp_hysteresis", {"dph": 0.1}),
        ("temp_rate_bias", {"dph_per_c_per_min": 0.2}),
        ("table_angle_harmonic", {"amplitude_dph": 0.3, "phase_deg": 20.0}),
        ("periodic_interference", {"freq_hz": 12.48, "amplitude_dph": 0.5}),
        ("markov_bias", {"sigma_dph": 0.05, "tau_s": 300.0}),
    ]:
        model = model.with_effect(EffectSpec(name, params))
    return model


def stream(model: GyroModel, fs_hz: float, seconds: float, block_s: float) -> int:
    """Stream ``seconds`` of data through a fresh simulator; return the sample count."""
    sim = GyroSimulator(model, fs_hz, seed=1)
    block = int(round(block_s * fs_hz))
    total = int(round(seconds * fs_hz))
    done = 0
    while done < total:
        n = min(block, total - done)
        t = (done + np.arange(n)) / fs_hz
        rate = 10.0 * np.sign(np.sin(2 * np.pi * t / 600.0))   # ±10 deg/s dwells
        chamber = 25.0 + 15.0 * np.sin(2 * np.pi * t / 7200.0)  # slow thermal cycle
        sim.generate(rate, chamber)
        done += n
    return total


def run(model: GyroModel, fs_hz: float, hours: float, block_s: float) -> tuple[float, int, float]:
    """(elapsed s, samples, peak traced MiB). Timed without tracemalloc, which slows numpy;
    the memory pass streams 10 blocks, enough for the steady state of a streaming generator."""
    start = time.perf_counter()
    samples = stream(model, fs_hz, hours * 3600.0, block_s)
    elapsed = time.perf_counter() - start
    tracemalloc.start()
    stream(model, fs_hz, 10 * block_s, block_s)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return elapsed, samples, peak / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0, help="hours of data per case (>= 1)")
    parser.add_argument("--block-s", type=float, default=60.0, help="seconds per generate() call")
    parser.add_argument("--rates", type=float, nargs="+", default=[200.0, 2000.0])
    args = parser.parse_args()
    cases = [
        ("nominal FOG + 6 effects", nominal_fog_with_effects()),
        ("RLG, quantization", load_model(MODELS / "rlg-dithered.yaml")),
    ]
    print(f"{'model':<26}{'fs Hz':>8}{'samples':>12}{'Msamples/s':>12}{'s per h':>10}{'peak MiB':>10}")
    for label, model in cases:
        for fs in args.rates:
            elapsed, samples, peak = run(model, fs, args.hours, args.block_s)
            print(f"{label:<26}{fs:>8g}{samples:>12d}{samples / elapsed / 1e6:>12.2f}"
                  f"{elapsed / args.hours:>10.2f}{peak:>10.1f}")
    maxrss_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"process max RSS: {maxrss_mib:.0f} MiB")


if __name__ == "__main__":
    main()
