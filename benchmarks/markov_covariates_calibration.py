"""How often the Markov-covariate test (analysis/discrepancy/markov_covariates.py) refuses a true Markov bias.

Each record is a simulated log of a profile (the own 15-min, 400 Hz thermal
shock, Q2 or P1) with a true markov_bias at 10σ (``sized_markov``), the nominal
model refitted to it with the model's noise (``discrepancy_scenarios.base_refit``),
the whole-record Markov test fitted to that residual as the workflow does, and
the covariate test run on that fit. Its level is COVARIATE_ALPHA = 0.5 %, so at
most about 0.5 % of true Markov records should be refused. Also: the same on
effect-free records (the Markov reading the test would see if a Markov bias were
about to be named on a control), and the test's CPU per call.

    .venv/bin/python benchmarks/markov_covariates_calibration.py --records 200 --profiles shock:12,shock:150
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import argparse
import time

import discrepancy_scenarios as scenarios  # noqa: E402
import numpy as np
from threadpoolctl import threadpool_limits
from validate_markov_covariates import profile  # noqa: E402

from gyrocal.analysis.discrepancy.context import markov_test
from gyrocal.analysis.discrepancy.markov_covariates import covariate_test

SEED0 = 64000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=100)
    parser.add_argument("--profiles", default="shock:12,shock:150,Q2:30,Q2:300,P1:1000",
                        help="profile:τ pairs (τ 0: effect-free records)")
    args = parser.parse_args()
    for item in args.profiles.split(","):
        pname, tau = item.split(":")
        prof = profile(pname)
        hidden = [scenarios.sized_markov(10.0, float(tau), prof)] if float(tau) > 0 else []
        refused, cpu, families = 0, [], {}
        for k in range(args.records):
            ctx, fit = scenarios.base_refit(prof, SEED0 + k, hidden)
            markov = markov_test(ctx, fit)
            start = time.process_time()
            verdict = covariate_test(ctx, fit, markov)
            cpu.append(time.process_time() - start)
            if verdict.why is not None:
                refused += 1
                families[verdict.family] = families.get(verdict.family, 0) + 1
        what = f"markov_bias τ {tau} s (10σ)" if float(tau) > 0 else "effect-free"
        print(f"{pname} {what}: refused {refused}/{args.records} ({100.0 * refused / args.records:.1f} %) "
              f"{families or ''}; CPU per call median {np.median(cpu):.3f} s, max {np.max(cpu):.3f} s",
              flush=True)


if __name__ == "__main__":
    with threadpool_limits(limits=1, user_api="blas"):
        main()
