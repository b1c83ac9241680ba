"""How often the Gauss–Markov shape tests (analysis/discrepancy/process_shape.py) refuse a true Markov bias.

Each record is one-second bin means of white rate noise plus a first-order
Gauss–Markov process (its σ set so the Markov test's expected likelihood ratio
is ``--snr``²), with the model's flicker term as the workflow's null has it; the
Markov test (stochastic.WhittleTest) is fitted to it as the workflow does, and
both shape tests are run on that fit. Their level is α/2 each, so at most
α = 2 % of true Markov records should be refused. Also reports the CPU of one
call, and, with ``--telegraph``, the detection rate on a two-level switching
bias of the same spectrum (mean dwell 2τ, same variance).

    .venv/bin/python benchmarks/process_shape_calibration.py --records 200 --tau 20,120,900 --hours 1.5
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from threadpoolctl import threadpool_limits

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.process_shape import gauss_markov_shape
from gyrocal.analysis.discrepancy.stochastic import WhittleTest, fine_bins

NOISE = NoiseModel(arw_deg_per_rth=0.01, bias_instability_dph=0.03)
FS_HZ = 1.0


def _sigma_for(test: WhittleTest, snr: float, tau_s: float) -> float:
    lo, hi = math.log(1e-4), math.log(1e3)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if test.expected_lr(math.exp(mid), tau_s) < snr * snr else (lo, mid)
    return math.exp(0.5 * (lo + hi))


def _record(n: int, sigma: float, tau_s: float, telegraph: bool, rng: np.random.Generator) -> np.ndarray:
    white = 60.0 * NOISE.arw_deg_per_rth * rng.standard_normal(n)
    if telegraph:
        level, t, out = rng.integers(2), 0, np.empty(n)
        while t < n:
            dwell = int(rng.exponential(2.0 * tau_s)) + 1
            out[t:t + dwell] = sigma * (2 * level - 1)
            level, t = 1 - level, t + dwell
        return white + out
    phi = math.exp(-1.0 / tau_s)
    drive = sigma * math.sqrt(1.0 - phi * phi) * rng.standard_normal(n)
    x = np.empty(n)
    x[0] = sigma * rng.standard_normal()
    for k in range(1, n):
        x[k] = phi * x[k - 1] + drive[k]
    return white + x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=100)
    parser.add_argument("--tau", default="20,120,900")
    parser.add_argument("--hours", type=float, default=1.5)
    parser.add_argument("--snr", type=float, default=10.0)
    parser.add_argument("--telegraph", action="store_true")
    args = parser.parse_args()
    n = int(args.hours * 3600.0)
    t = np.arange(n) / FS_HZ
    bins = fine_bins(t, FS_HZ)
    whittle = WhittleTest(NOISE, bins, FS_HZ)
    rng = np.random.default_rng(77)
    for tau_s in (float(x) for x in args.tau.split(",")):
        sigma = _sigma_for(whittle, args.snr, tau_s)
        refused = {"level": 0, "flicker": 0}
        cpu = []
        for _ in range(args.records):
            y = _record(n, sigma, tau_s, args.telegraph, rng)
            markov = whittle.test(y, rng, 50)
            start = time.process_time()
            verdict = gauss_markov_shape(NOISE, bins, FS_HZ, y, markov)
            cpu.append(time.process_time() - start)
            refused["level"] += verdict.level_statistic > verdict.level_limit
            refused["flicker"] += (verdict.flicker_statistic > verdict.flicker_limit
                                   and verdict.level_statistic <= verdict.level_limit)
        total = refused["level"] + refused["flicker"]
        kind = "telegraph (dwell 2τ)" if args.telegraph else "Gauss–Markov"
        print(f"{kind} τ {tau_s:g} s, σ {sigma:.3g} deg/h, {args.hours:g} h: refused {total}/{args.records} "
              f"({100.0 * total / args.records:.1f} %; two levels {refused['level']}, flicker "
              f"{refused['flicker']}), CPU per call median {np.median(cpu):.3f} s", flush=True)


if __name__ == "__main__":
    with threadpool_limits(limits=1, user_api="blas"):
        main()
