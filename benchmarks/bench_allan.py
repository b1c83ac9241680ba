"""Overlapping ADEV: gyrocal.analysis.allan.deviation against allantools.oadev, side by side.

Prints one table: wall time of each on the same data and τ grid (runs
interleaved, median of --repeats), the pairwise speed-up, the largest relative difference between the two curves, and the
peak memory that our function allocates (tracemalloc) relative to the input.

    .venv/bin/python benchmarks/bench_allan.py            # 10 M samples, ~100 τ
    .venv/bin/python benchmarks/bench_allan.py --n 1e6    # quick
"""

from __future__ import annotations

import argparse
import statistics
import time
import tracemalloc

import numpy as np

from gyrocal.analysis.allan.deviation import log_spaced_m, overlapping_adev


def _args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e7, help="number of rate samples")
    parser.add_argument("--taus", type=int, default=100, help="requested log-spaced τ count")
    parser.add_argument("--rate-hz", type=float, default=100.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--skip-allantools", action="store_true")
    parser.add_argument("--repeats", type=int, default=3, help="interleaved runs of each")
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


def _timed(call) -> tuple[float, object]:
    start = time.perf_counter()
    result = call()
    return time.perf_counter() - start, result


def main() -> None:
    args = _args()
    n = int(args.n)
    y = _gyro_like_rate(n, args.rate_hz, args.seed)
    m = log_spaced_m(n, count=args.taus)
    overlapping_adev(y[:100_000], args.rate_hz, confidence=None)  # compile / load the kernel
    import allantools

    plain, with_ci, reference = [], [], []
    for _ in range(args.repeats):  # interleaved, so drift of a shared machine hits all alike
        seconds, ours_plain = _timed(lambda: overlapping_adev(y, args.rate_hz, m=m,
                                                              confidence=None))
        plain.append(seconds)
        seconds, ours_ci = _timed(lambda: overlapping_adev(y, args.rate_hz, m=m))
        with_ci.append(seconds)
        if not args.skip_allantools:
            seconds, (taus_ref, adev_ref, _, _) = _timed(lambda: allantools.oadev(
                y, rate=args.rate_hz, data_type="freq", taus=m / args.rate_hz))
            reference.append(seconds)
    assert np.array_equal(ours_plain.adev, ours_ci.adev)
    # Memory in separate calls: tracemalloc's bookkeeping must not distort the timings.
    peak_plain = _peak_bytes(lambda: overlapping_adev(y, args.rate_hz, m=m, confidence=None))
    peak_ci = _peak_bytes(lambda: overlapping_adev(y, args.rate_hz, m=m))

    med = statistics.median
    print(f"samples: {n:,}   τ values: {m.size}   input: {y.nbytes / 1e6:.0f} MB   "
          f"median of {args.repeats} interleaved runs")
    print(f"{'implementation':<34}{'wall s (min-med-max)':>24}{'peak mem / input':>20}")
    for name, times, peak in (("gyrocal overlapping_adev", plain, peak_plain),
                              ("gyrocal overlapping_adev + CI", with_ci, peak_ci)):
        spread = f"{min(times):.2f}-{med(times):.2f}-{max(times):.2f}"
        print(f"{name:<34}{spread:>24}{peak / y.nbytes:>20.2f}")
    if args.skip_allantools:
        return
    spread = f"{min(reference):.2f}-{med(reference):.2f}-{max(reference):.2f}"
    print(f"{'allantools.oadev':<34}{spread:>24}{'-':>20}")
    if not np.allclose(taus_ref, ours_plain.tau_s, rtol=0, atol=0):
        raise SystemExit("τ grids differ between implementations")
    max_rel = float(np.max(np.abs(ours_plain.adev / adev_ref - 1.0)))
    ratios = [r / p for r, p in zip(reference, plain, strict=True)]
    ratios_ci = [r / p for r, p in zip(reference, with_ci, strict=True)]
    print(f"speed-up (plain): {med(ratios):.1f}x (pairwise median)   speed-up (with CI): "
          f"{med(ratios_ci):.1f}x   max relative difference: {max_rel:.2e}")


if __name__ == "__main__":
    main()
