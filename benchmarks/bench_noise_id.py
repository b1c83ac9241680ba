"""Noise-type identification per τ: gyrocal.analysis.allan.noise_id against allantools, side by side.

Both run Riley & Greenhall's lag-1 autocorrelation method on the same τ-averages
(the decimated phase of a gyro-like record, at most ``MAX_POINTS`` averages per τ,
as the Allan curve uses them). Prints the wall time of each (interleaved runs,
min-median-max), the peak memory each allocates (tracemalloc) and on how many τ
the two identify the same noise type; a third row runs our functions without the
one-BLAS-thread limit. allantools computes the autocorrelation with a Python loop
over the samples, which is why analysis/allan/noise_id.py keeps its own.

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
from gyrocal.analysis.allan.noise_id import (
    ALPHA_MAX,
    ALPHA_MIN,
    MIN_POINTS,
    alpha_per_m_from_decimated,
    identify_alpha_from_averages,
)

MAX_POINTS = 100_000  # identify_alpha_per_m's default


def _args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e6, help="number of rate samples")
    parser.add_argument("--taus", type=int, default=100, help="requested log-spaced τ count")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved runs of each")
    return parser.parse_args()


def _decimated_phase(n: int, count: int, seed: int) -> list[np.ndarray]:
    """Phase x[0], x[m], x[2m], … (up to MAX_POINTS averages) per τ of white rate noise
    plus a rate random walk: what the Allan pass hands to the identification."""
    rng = np.random.default_rng(seed)
    rate = rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 3e-3
    phase = np.concatenate(([0.0], np.cumsum(rate - rate.mean())))
    return [phase[: min(n // int(m), MAX_POINTS) * int(m) + 1 : int(m)]
            for m in log_spaced_m(n, count=count)]


def _identifiable(decimated: list[np.ndarray]) -> list[int]:
    return [i for i, points in enumerate(decimated) if points.size - 1 >= MIN_POINTS]


def _ours(decimated: list[np.ndarray]) -> list[int]:
    """The product's path (one BLAS thread), at the τ with enough averages."""
    alphas = alpha_per_m_from_decimated(decimated)
    return [int(alphas[i]) for i in _identifiable(decimated)]


def _ours_threaded_blas(decimated: list[np.ndarray]) -> list[int]:
    """The same functions without the one-thread limit (how it ran before)."""
    return [identify_alpha_from_averages(np.diff(decimated[i])) for i in _identifiable(decimated)]


def _allantools(decimated: list[np.ndarray]) -> list[int]:
    return [int(np.clip(allantools.autocorr_noise_id(np.diff(decimated[i]), 1, data_type="freq",
                                                     dmin=0, dmax=2)[0], ALPHA_MIN, ALPHA_MAX))
            for i in _identifiable(decimated)]


def _timed(call, decimated) -> tuple[float, list[int]]:
    start = time.perf_counter()
    result = call(decimated)
    return time.perf_counter() - start, result


def _peak_bytes(call, decimated) -> int:
    tracemalloc.start()
    try:
        call(decimated)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main() -> None:
    args = _args()
    decimated = _decimated_phase(int(args.n), args.taus, args.seed)
    runs = (("gyrocal noise_id", _ours), ("gyrocal, threaded BLAS", _ours_threaded_blas),
            ("allantools.autocorr_noise_id", _allantools))
    times: dict[str, list[float]] = {name: [] for name, _ in runs}
    types: dict[str, list[int]] = {}
    for _ in range(args.repeats):  # interleaved: drift of a shared machine hits all alike
        for name, call in runs:
            seconds, types[name] = _timed(call, decimated)
            times[name].append(seconds)
    med = statistics.median
    averages = sum(decimated[i].size - 1 for i in _identifiable(decimated))
    print(f"samples: {int(args.n):,}   τ: {len(decimated)} ({len(_identifiable(decimated))} "
          f"identifiable)   averages in all: {averages:,}   median of {args.repeats}")
    print(f"{'implementation':<34}{'wall s (min-med-max)':>24}{'peak MB':>10}")
    for name, call in runs:
        spread = f"{min(times[name]):.3f}-{med(times[name]):.3f}-{max(times[name]):.3f}"
        print(f"{name:<34}{spread:>24}{_peak_bytes(call, decimated) / 1e6:>10.1f}")
    ours, theirs = types["gyrocal noise_id"], types["allantools.autocorr_noise_id"]
    ratios = [t / o for t, o in zip(times["allantools.autocorr_noise_id"],
                                    times["gyrocal noise_id"], strict=True)]
    agree = sum(a == b for a, b in zip(ours, theirs, strict=True))
    print(f"speed-up over allantools: {med(ratios):.0f}x (pairwise median)   same noise type on "
          f"{agree} of {len(ours)} τ   types found: {sorted(set(ours))}")


if __name__ == "__main__":
    main()
