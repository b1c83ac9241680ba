"""Noise-type identification per τ: gyrocal.analysis.allan.noise_id against allantools, side by side.

Both run Riley & Greenhall's lag-1 autocorrelation method on the same τ-averages
(the decimated phase of a gyro-like record, at most ``MAX_POINTS`` averages per τ,
as the Allan curve uses them). Prints the wall time of each (interleaved runs,
min-median-max), the peak memory each allocates (tracemalloc) and on how many τ
the two identify the same noise type. allantools computes the autocorrelation with
a Python loop over the samples, which is why analysis/allan/noise_id.py keeps its own.

    .venv/bin/python benchmarks/bench_noise_id.py             # 1 M samples, ~100 τ
    .venv/bin/python benchmarks/bench_noise_id.py --n 1e7     # an overnight record (slow: allantools)
"""

from __future__ import annotations

import argparse
import statistics
import time
import tracemalloc

import allantools
import numpy as np

from gyrocal.analysis.allan.deviation import log_spaced_m
from gyrocal.analysis.allan.noise_id import ALPHA_MAX, ALPHA_MIN, MIN_POINTS, identify_alpha_from_averages

MAX_POINTS = 100_000  # identify_alpha_per_m's default


def _args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e6, help="number of rate samples")
    parser.add_argument("--taus", type=int, default=100, help="requested log-spaced τ count")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved runs of each")
    return parser.parse_args()


def _averages_per_tau(n: int, count: int, seed: int) -> list[np.ndarray]:
    """τ-averages (up to MAX_POINTS) of white rate noise plus a rate random walk, per τ."""
    rng = np.random.default_rng(seed)
    rate = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 3e-3
    phase = np.concatenate(([0.0], np.cumsum(rate - rate.mean())))
    averages = []
    for m in log_spaced_m(n, count=count):
        points = phase[: min(n // int(m), MAX_POINTS) * int(m) + 1 : int(m)]
        if points.size - 1 >= MIN_POINTS:
            averages.append(np.diff(points))
    return averages


def _ours(averages: list[np.ndarray]) -> list[int]:
    return [identify_alpha_from_averages(z) for z in averages]


def _allantools(averages: list[np.ndarray]) -> list[int]:
    return [int(np.clip(allantools.autocorr_noise_id(z, 1, data_type="freq", dmin=0, dmax=2)[0],
                        ALPHA_MIN, ALPHA_MAX)) for z in averages]


def _timed(call, averages) -> tuple[float, list[int]]:
    start = time.perf_counter()
    result = call(averages)
    return time.perf_counter() - start, result


def _peak_bytes(call, averages) -> int:
    tracemalloc.start()
    try:
        call(averages)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main() -> None:
    args = _args()
    averages = _averages_per_tau(int(args.n), args.taus, args.seed)
    ours_s, theirs_s = [], []
    for _ in range(args.repeats):  # interleaved: drift of a shared machine hits both alike
        seconds, ours = _timed(_ours, averages)
        ours_s.append(seconds)
        seconds, theirs = _timed(_allantools, averages)
        theirs_s.append(seconds)
    agree = sum(a == b for a, b in zip(ours, theirs, strict=True))
    med = statistics.median
    points = sum(z.size for z in averages)
    print(f"samples: {int(args.n):,}   identifiable τ: {len(averages)}   averages in all: {points:,}")
    print(f"{'implementation':<34}{'wall s (min-med-max)':>24}{'peak MB':>10}")
    for name, times, call in (("gyrocal noise_id", ours_s, _ours),
                              ("allantools.autocorr_noise_id", theirs_s, _allantools)):
        spread = f"{min(times):.3f}-{med(times):.3f}-{max(times):.3f}"
        print(f"{name:<34}{spread:>24}{_peak_bytes(call, averages) / 1e6:>10.1f}")
    ratios = [t / o for t, o in zip(theirs_s, ours_s, strict=True)]
    print(f"speed-up: {med(ratios):.0f}x (pairwise median)   same noise type on {agree} of "
          f"{len(averages)} τ   types: {sorted(set(ours))}")


if __name__ == "__main__":
    main()
