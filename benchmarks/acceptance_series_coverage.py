"""Coverage of the acceptance series' intervals over seeded dry runs (issue 25).

Runs procedures/acceptance-series.yaml on the simulated station (gyro-models/series-fog.yaml)
with seeds 1..N and counts, per covered test, how often the simulator's hand-typed truth
lies inside estimate ± U (as docs/uncertainty-coverage.md does for the GUM budgets).

    .venv/bin/python benchmarks/acceptance_series_coverage.py --runs 8
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
from pathlib import Path

from gyrocal.cli import main

REPO = Path(__file__).resolve().parents[1]
DEAD_ZONE_DPS = 0.025      # gyro-models/series-fog.yaml, typed
SATURATION_DPS = {"positive": 320.0, "negative": 270.0}
BANDWIDTH_HZ = 1.0         # rate_bandwidth, typed
PHASE_AT_HALF_HZ_DEG = -26.565051177   # −atan(0.5 Hz / 1 Hz)
STARTUP_S = 0.8            # stations/sim-series.yaml simulation.gyro_startup_s, typed
WARMUP_TAU_S = 10.0        # warmup_transient, typed
REPEATABILITY_DPH = 2.009  # √(turn_on_bias_dph 2² + (0.6 deg/h/√Hz / √10 s)²)


def one_run(seed: int, folder: Path) -> tuple[int, str, dict | None]:
    """(exit code, console text, results) of one seeded dry run."""
    out = folder / f"run-{seed}"
    console = io.StringIO()
    with contextlib.redirect_stdout(console), contextlib.redirect_stderr(console):
        code = main(["run", str(REPO / "procedures" / "acceptance-series.yaml"), "--sim",
                     "--out", str(out), "--seed", str(seed)])
    path = out / "report" / "results.json"
    return code, console.getvalue(), json.loads(path.read_text()) if path.is_file() else None


def main_cli() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=8)
    runs = parser.parse_args().runs
    covered = failed = 0
    limits = {"positive": 0, "negative": 0}
    response = {"bandwidth": 0, "phase": 0}
    power = {"turn-on time": 0, "warm-up tau": 0, "repeatability": 0}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, runs + 1):
            code, console, results = one_run(seed, Path(tmp))
            if code != 0 or results is None:
                failed += 1
                print(f"seed {seed}: run ended with exit {code}, not counted: "
                      f"{console.strip().splitlines()[-1:]}")
                continue
            zero = next(t for t in results["threshold"]["tests"] if t["base_rate_dps"] == 0)
            inside = zero["estimate_dps"] is not None and \
                abs(zero["estimate_dps"] - DEAD_ZONE_DPS) <= zero["U_dps"]
            covered += inside
            print(f"seed {seed}: threshold {zero['threshold_dps']} in ({zero['below_dps']}, "
                  f"{zero['threshold_dps']}] U {zero['U_dps']:.4g}: {'covered' if inside else 'MISSED'}")
            for walk in results["rate_limits"]["tests"]:
                truth = SATURATION_DPS[walk["direction"]]
                hit = walk["estimate_dps"] is not None and \
                    abs(walk["estimate_dps"] - truth) <= walk["U_dps"]
                limits[walk["direction"]] += hit
                print(f"  max rate {walk['direction']}: {walk['max_dps']} (next {walk['next_dps']}) "
                      f"U {walk['U_dps']:.4g}: {'covered' if hit else 'MISSED'}")
            response_hits = _frequency_response(results["frequency_response"])
            for key, hit in response_hits.items():
                response[key] += hit
            for key, hit in _turn_on(results).items():
                power[key] += hit
    done = runs - failed
    print(f"{done} of {runs} runs completed with every limit passed")
    print(f"threshold (dead zone {DEAD_ZONE_DPS} deg/s): {covered}/{done} covered")
    for direction, hits in limits.items():
        print(f"max input rate {direction} (truth {SATURATION_DPS[direction]:g} deg/s): "
              f"{hits}/{done} covered")
    print(f"bandwidth (truth {BANDWIDTH_HZ:g} Hz): {response['bandwidth']}/{done} covered")
    print(f"phase at 0.5 Hz (truth {PHASE_AT_HALF_HZ_DEG:.3f} deg): {response['phase']}/{done} "
          "covered")
    truths = {"turn-on time": f"{STARTUP_S:g} s", "warm-up tau": f"{WARMUP_TAU_S:g} s",
              "repeatability": f"{REPEATABILITY_DPH:g} deg/h"}
    for key, hits in power.items():
        print(f"{key} (truth {truths[key]}): {hits}/{done} covered")


def _turn_on(results: dict) -> dict[str, bool]:
    """Turn-on time, warm-up τ and repeatability against the typed truths, printed."""
    on = results["turn_on"]["tests"][0]
    rep = results["turn_on_repeatability"]["tests"][0]
    hits = {"turn-on time": abs(on["time_to_first_data_s"] - STARTUP_S)
            <= on["U_time_to_first_data_s"],
            "warm-up tau": abs(on["warmup_tau_s"] - WARMUP_TAU_S) <= on["U_warmup_tau_s"],
            "repeatability": abs(rep["std_dph"] - REPEATABILITY_DPH) <= rep["U_std_dph"]}
    print(f"  turn-on {on['time_to_first_data_s']:.3f} s, tau {on['warmup_tau_s']:.2f} "
          f"U {on['U_warmup_tau_s']:.2g} s, repeatability {rep['std_dph']:.3f} "
          f"U {rep['U_std_dph']:.2g} deg/h: "
          + ", ".join(f"{k} {'covered' if v else 'MISSED'}" for k, v in hits.items()))
    return hits


def _frequency_response(section: dict) -> dict[str, bool]:
    """Bandwidth and phase at the stated frequency against the typed truths, printed."""
    test = section["tests"][0]
    band, phase = section["bandwidth_hz"], section["phase_deg"]
    hits = {"bandwidth": band is not None and abs(band - BANDWIDTH_HZ) <= test["U_bandwidth_hz"],
            "phase": phase is not None and abs(phase - PHASE_AT_HALF_HZ_DEG) <= test["U_phase_deg"]}
    print(f"  bandwidth {band:.5f} U {test['U_bandwidth_hz']:.2g} Hz: "
          f"{'covered' if hits['bandwidth'] else 'MISSED'}; phase at 0.5 Hz {phase:.3f} "
          f"U {test['U_phase_deg']:.2g} deg: {'covered' if hits['phase'] else 'MISSED'}")
    return hits


if __name__ == "__main__":
    main_cli()
