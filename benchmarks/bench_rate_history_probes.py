"""CPU the rate-history probes (spin heating, net table turns) add to one discrepancy run.

On a P2-sized record (2.6 h at 100 Hz, 930 000 samples, 2000 bins, 500 null draws, as
``analyse``'s defaults) and on a 10 M-sample record (the same profile at 1075 Hz): the
first call pays the per-sample work (|ω|, ω² and ∫ω dt averaged into the bins, cached for
the record), every later call (each search round and the adequacy pass) only the binned
filter and the projections. Beside them, the decaying step (the probe of the same kind,
a single-column grid) as the reference.

    .venv/bin/python benchmarks/bench_rate_history_probes.py
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

import discrepancy_scenarios as scenarios  # noqa: E402

from gyrocal.analysis.discrepancy.noise_model import NoiseModel  # noqa: E402
from gyrocal.analysis.discrepancy.probes import (  # noqa: E402
    ProbeInputs,
    ProbeKind,
    _one_shape,
    decaying_step_probe,
    spin_heat_probe,
)
from gyrocal.analysis.discrepancy.scoring import Whitener, gls_fit  # noqa: E402
from gyrocal.analysis.discrepancy.segments import make_bins  # noqa: E402
from gyrocal.analysis.discrepancy.signatures import DesignBuilder  # noqa: E402


def cpu(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


def measure(prof: scenarios.Profile, max_bins: int = 2000, n_null: int = 500) -> dict[str, float]:
    nominal = scenarios.nominal_model()
    bins = make_bins(prof.t_s, prof.fs_hz, max_bins=max_bins)
    builder = DesignBuilder(prof.inputs, bins)
    noise = NoiseModel.of_model(nominal)
    whitener = Whitener(noise.bin_covariance(bins.centre_s, bins.width_s, bins.samples_per_bin, prof.fs_hz))
    fit = gls_fit(builder, whitener, bins.mean(builder.rate_dph(scenarios.true_base(nominal))), nominal)
    z = np.random.default_rng(1).standard_normal((bins.n_bins, n_null))
    full = ProbeInputs(prof.t_s, prof.table_rate_dps, prof.chamber_temp_c, np.zeros_like(prof.t_s))
    x = replace(full, bins=bins, _cache={})

    def both() -> None:
        spin_heat_probe(fit, whitener, x, z, 0.02)
        _one_shape(ProbeKind.NET_TURNS, x, fit, whitener, z, 0.02)

    first = cpu(both)
    later = min(cpu(both) for _ in range(5))
    decay = min(cpu(lambda: decaying_step_probe(fit, whitener, x, z, 0.02)) for _ in range(5))
    return {"samples": len(prof.t_s), "first call s": first, "later call s": later, "decaying step s": decay}


def main() -> None:
    for fs_hz in (100.0, 1075.0):
        prof = scenarios.five_temperature_profile(fs_hz=fs_hz)
        with threadpool_limits(limits=1, user_api="blas"):     # as analyse() runs
            out = measure(prof)
        print(", ".join(f"{k} {v:.4g}" for k, v in out.items()))


if __name__ == "__main__":
    main()
