"""Overlapping ADEV: gyrocal.reports.allan against allantools.oadev, side by side.

Prints one table: wall time of each on the same data and τ grid, the
speed-up, the largest relative difference between the two curves, and the
peak memory that our function allocates (tracemalloc) relative to the input.

    .venv/bin/python benchmarks/bench_allan.py            # 10 M samples, ~100 τ
    .venv/bin/python benchmarks/bench_allan.py --n 1e6    # quick
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from gyrocal.reports.allan import log_spaced_m, overlapping_adev


def _args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e7, help="number of rate samples")
    parser.add_argument("--taus", type=int, default=100, help="requested log-spaced τ count")
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--skip-allantools", action="store_true")
    return parser.parse_args()


def _gyro_like_rate(n: int, rate_hz: float, seed: int) -> np.ndarray:
    """Bias + white rate noise + a little rate random walk, in deg/h."""
    rng = np.random.default_rng(seed)
    rate = rng.standard_normal(n)
    rate *= 0.01 * 60.0 * np.sqrt(rate_hz)  # N = 0.01 deg/√h
    rate += np.cumsum(rng.standard_normal(n)) * (0.05 * np.sqrt(1.0 / rate_hz / 3600.0))
    rate += 2.0
    return rate


def _peak_bytes(call) -> int:
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main() -> None:
    args = _args()
    n = int(args.n)
    y = _gyro_like_rate(n, args.rate_hz, args.seed)
    m = log_spaced_m(n, count=args.taus)

    start = time.perf_counter()
    ours_plain = overlapping_adev(y, args.rate_hz, m=m, confidence=None)
    ours_plain_s = time.perf_counter() - start
    start = time.perf_counter()
    ours_ci = overlapping_adev(y, args.rate_hz, m=m)
    ours_ci_s = time.perf_counter() - start
    assert np.array_equal(ours_plain.adev, ours_ci.adev)
    # Memory in separate calls: tracemalloc's bookkeeping must not distort the timings.
    peak_plain = _peak_bytes(lambda: overlapping_adev(y, args.rate_hz, m=m, confidence=None))
    peak_ci = _peak_bytes(lambda: overlapping_adev(y, args.rate_hz, m=m))

    print(f"samples: {n:,}   τ values: {m.size}   input: {y.nbytes / 1e6:.0f} MB")
    print(f"{'implementation':<34}{'wall s':>10}{'peak mem / input':>20}")
    print(f"{'gyrocal overlapping_adev':<34}{ours_plain_s:>10.2f}{peak_plain / y.nbytes:>20.2f}")
    print(f"{'gyrocal overlapping_adev + CI':<34}{ours_ci_s:>10.2f}{peak_ci / y.nbytes:>20.2f}")
    if args.skip_allantools:
        return
    import allantools

    start = time.perf_counter()
    taus_ref, adev_ref, _, _ = allantools.oadev(y, rate=args.rate_hz, data_type="freq",
                                                taus=m / args.rate_hz)
    ref_s = time.perf_counter() - start
    print(f"{'allantools.oadev':<34}{ref_s:>10.2f}{'-':>20}")
    if not np.allclose(taus_ref, ours_plain.tau_s, rtol=0, atol=0):
        raise SystemExit("τ grids differ between implementations")
    max_rel = float(np.max(np.abs(ours_plain.adev / adev_ref - 1.0)))
    print(f"speed-up (plain): {ref_s / ours_plain_s:.1f}x   speed-up (with CI): "
          f"{ref_s / ours_ci_s:.1f}x   max relative difference: {max_rel:.2e}")


if __name__ == "__main__":
    main()
