"""Measured coverage of the GUM 95 % intervals over simulated calibrations with a known truth.

    .venv/bin/python benchmarks/uncertainty_coverage.py [--runs 200] [--seed 0]

Each run is a fast model of a three-temperature calibration (not the full
procedure engine: the point is the statistics of the analysis, not the
instruments): ± 10/50/100 deg/s dwells of 20 s and a 60 s static hold at −20,
25 and 70 °C, 200 Hz, the gyro noise from models/noise.py (white rate noise
N = 0.01 deg/√h plus a Gauss–Markov bias drift σ = 0.05 deg/h, τ = 5 s, so
the batch means matter), and the reference instruments' errors drawn once
per run from the same rectangular distributions the budget declares
(table rate ±10 ppm, chamber temperature ±0.5 °C). The truth is the model's
SF(T) = 1 + 1e-6·(50 + 20·(T − 25)) and bias(T) = 2 + 0.03·(T − 25) deg/h,
evaluated at each run's actual chamber temperature (the measurand "at the
setpoint" is the value at the chamber's condition; the chamber's error enters
the temperature sensitivities, whose truth is exact).

The analysis is the report's: dwell means with batch-means standard errors
(metrology/gum.py) and the budgets of metrology/uncertainty.py. Prints the
coverage table (markdown) that docs/uncertainty-coverage.md keeps.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from gyrocal.metrology.gum import batch_mean_sem
from gyrocal.metrology.uncertainty import (
    MeanU,
    TypeB,
    bias_uncertainty_static,
    sf_temperature_uncertainty,
    slope_uncertainty,
    sweep_uncertainty,
)
from gyrocal.models.noise import GaussMarkov, WhiteRateNoise

FS_HZ = 200.0
TEMPS_C = (-20.0, 25.0, 70.0)
RATES_DPS = (-100.0, -50.0, -10.0, 10.0, 50.0, 100.0)
DWELL_S, HOLD_S = 20.0, 60.0
TYPE_B = TypeB(table_rate_accuracy_ppm=10.0, chamber_temp_accuracy_c=0.5,
               latitude_accuracy_deg=0.0, axis_tilt_deg=0.0)


def true_sf(temp_c: float) -> float:
    return 1.0 + 1e-6 * (50.0 + 20.0 * (temp_c - 25.0))


def true_bias_dph(temp_c: float) -> float:
    return 2.0 + 0.03 * (temp_c - 25.0)


def one_run(seed: int) -> dict[str, tuple[float, float, float]]:
    """{quantity: (estimate, U, truth)} for one simulated calibration."""
    rng = np.random.default_rng(seed)
    white = WhiteRateNoise(0.01, FS_HZ, seed=rng.integers(2**32))
    drift = GaussMarkov(0.05, 5.0, FS_HZ, seed=rng.integers(2**32))
    rate_error = rng.uniform(-1.0, 1.0) * TYPE_B.table_rate_accuracy_ppm * 1e-6
    actual = {t: t + rng.uniform(-1.0, 1.0) * TYPE_B.chamber_temp_accuracy_c for t in TEMPS_C}

    def mean_u(temp_c: float, rate_dps: float, seconds: float) -> MeanU:
        n = int(seconds * FS_HZ)
        noise_dps = (white.generate(n) + drift.generate(n)) / 3600.0
        sf = true_sf(actual[temp_c])
        output = sf * (rate_dps * (1.0 + rate_error) + true_bias_dph(actual[temp_c]) / 3600.0
                       + noise_dps)
        sem, dof = batch_mean_sem(output)
        return MeanU(temp_c, rate_dps, float(output.mean()), sem, dof, f"{rate_dps:+g}")

    out: dict[str, tuple[float, float, float]] = {}
    sweeps, sf_u, bias_u = [], {}, {}
    for t in TEMPS_C:
        sweep = [mean_u(t, r, DWELL_S) for r in RATES_DPS]
        sweeps += sweep
        budget = sweep_uncertainty(sweep, TYPE_B)
        sf_u[t] = budget["sf"]
        hold = mean_u(t, 0.0, HOLD_S)
        bias_u[t] = bias_uncertainty_static(hold, budget["sf"], None, TYPE_B)
        if t == 25.0:
            out["SF at 25 °C"] = (budget["sf"].value, budget["sf"].U, true_sf(actual[t]))
            out["bias at 25 °C (deg/h)"] = (bias_u[t].value, bias_u[t].U,
                                            true_bias_dph(actual[t]))
            out["asymmetry (ppm)"] = (budget["asymmetry_ppm"].value, budget["asymmetry_ppm"].U,
                                      0.0)
            nl = budget["nonlinearity_max_ppm_fs"]
            out["nonlinearity max (ppm FS)"] = (nl.value, nl.U, 0.0)
            rms = budget["nonlinearity_rms_pct"]
            out["nonlinearity RMS (%)"] = (rms.value, rms.U, 0.0)
    tempco = sf_temperature_uncertainty(sweeps, TYPE_B, 25.0)["sensitivity_ppm_per_c"]
    out["SF tempco (ppm/°C)"] = (tempco.value, tempco.U, 20.0 / true_sf(25.0))
    slope = slope_uncertainty(list(TEMPS_C), [bias_u[t] for t in TEMPS_C], TYPE_B, "bias")
    out["bias tempco (deg/h/°C)"] = (slope.value, slope.U, 0.03)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    start = time.perf_counter()
    hits: dict[str, list[bool]] = {}
    ratio: dict[str, list[float]] = {}
    for i in range(args.runs):
        for name, (value, expanded, truth) in one_run(args.seed + i).items():
            hits.setdefault(name, []).append(abs(value - truth) <= expanded)
            ratio.setdefault(name, []).append(abs(value - truth) / expanded * 1.96)
    elapsed = time.perf_counter() - start
    print(f"{args.runs} simulated calibrations, seeds {args.seed}..{args.seed + args.runs - 1}, "
          f"{elapsed:.0f} s\n")
    print("| quantity | coverage of value ± U (target 95 %) | 95 % binomial band | "
          "median \\|error\\|·1.96/U |")
    print("|---|---|---|---|")
    band = 1.96 * math.sqrt(0.95 * 0.05 / args.runs) * 100
    for name, values in hits.items():
        print(f"| {name} | {100 * np.mean(values):.1f} % | 95 ± {band:.1f} % | "
              f"{np.median(ratio[name]):.2f} |")


if __name__ == "__main__":
    main()
