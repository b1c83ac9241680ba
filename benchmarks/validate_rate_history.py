"""Rate-history structure (spin heating, cable wind-up) on own cases: unexplained, not a catalogue name.

Two rig effects depend on the table's rate *history*, not on the rate now: a bias from
the heat a spinning table (or gyro) builds up, ω² or |ω| through a first-order memory,
and a bias ∝ the net table angle turned since the start (a cable winding up). Their
shapes here are this tool's own (own τ, own profiles P1, Q1–Q3, own seeds; never the
held-out sets) and are made with scipy's filter, not with the probe's code. Measures:

* unknowns (10σ, known-shape SNR): `unexplained`, the probe named in `where`, claims;
* the catalogue neighbours at 10σ (markov_bias τ 300 s, sf_asymmetry, bias_ramp,
  warmup_transient, sf_nonlinearity_quadratic, thermal_lag): named first, at what;
* effect-free controls: any claim, `unexplained`, and whether a rate-history probe said so.

    .venv/bin/python benchmarks/validate_rate_history.py --group unknown --seeds 2 --out /tmp/u.jsonl
    .venv/bin/python benchmarks/validate_rate_history.py --table /tmp/u.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

import discrepancy_scenarios as scenarios  # noqa: E402
import validate_discrepancy as inside  # noqa: E402
import validate_discrepancy_outside as outside  # noqa: E402

from gyrocal.analysis.discrepancy.noise_model import NoiseModel  # noqa: E402
from gyrocal.analysis.discrepancy.probes import ProbeInputs, ProbeKind, all_probes  # noqa: E402
from gyrocal.analysis.discrepancy.scoring import Whitener, gls_fit, order_statistic_quantile  # noqa: E402
from gyrocal.analysis.discrepancy.segments import make_bins  # noqa: E402
from gyrocal.analysis.discrepancy.signatures import DesignBuilder, placeholder_spec  # noqa: E402
from gyrocal.analysis.discrepancy.workflow import analyse  # noqa: E402

NEIGHBOURS = ("markov_bias", "sf_asymmetry", "bias_ramp", "warmup_transient", "sf_nonlinearity_quadratic",
              "thermal_lag")
MARKOV_TAU_S = 300.0
#: words of ``where`` that name each unknown's probe
WORDS = {"heat": "spin heating", "turns": "net table turns"}


def lagged(u: np.ndarray, fs_hz: float, tau_s: float) -> np.ndarray:
    """u through a first-order memory of ``tau_s`` (unit gain, starting from zero)."""
    a = np.exp(-1.0 / (fs_hz * tau_s))
    return lfilter([1.0 - a], [1.0, -a], u)


def net_turns(p: scenarios.Profile) -> np.ndarray:
    return np.cumsum(p.table_rate_dps) / p.fs_hz / 360.0


#: own shapes (per sample, deg/h before sizing)
UNKNOWN = {
    "spin heating ω² τ 150 s": lambda p: lagged(p.table_rate_dps ** 2, p.fs_hz, 150.0),
    "spin heating ω² τ 800 s": lambda p: lagged(p.table_rate_dps ** 2, p.fs_hz, 800.0),
    "spin heating |ω| τ 400 s": lambda p: lagged(np.abs(p.table_rate_dps), p.fs_hz, 400.0),
    "net table turns": net_turns,
}


def profile(name: str) -> scenarios.Profile:
    return inside.profile(name) if name.startswith("P") else outside.profile(name)


def run(pname: str, case: str, seed: int, snr: float = 10.0) -> dict:
    prof = profile(pname)
    extra, hidden = None, []
    if case in UNKNOWN:
        extra = scenarios.sized_extra(UNKNOWN[case](prof), snr, prof, max_bins=1000)
    elif case == "markov_bias":
        hidden = [scenarios.sized_markov(snr, MARKOV_TAU_S, prof)]
    elif case != "control":
        hidden = [scenarios.sized_effect(case, snr, prof, max_bins=1000)]
    samples = scenarios.simulate_log(prof, hidden, seed, extra_dph=extra)
    start = time.process_time()
    result = analyse(scenarios.nominal_model(), scenarios.as_measured_log(samples), seed=seed,
                     n_null=300, max_bins=1000)
    return {"profile": pname, "case": case, "seed": seed, "snr": snr,
            "found": [[f.name, round(f.probability, 4)] for f in result.found],
            "unexplained": result.unexplained, "where": result.where[:300],
            "cpu_s": round(time.process_time() - start, 2)}


def jobs(group: str, profiles: list[str], seeds: int, controls: int) -> list[tuple[str, str, int]]:
    out = []
    for p in profiles:
        if group == "unknown":
            out += [(p, c, 29900 + s) for c in UNKNOWN for s in range(seeds)]
        elif group == "neighbour":
            out += [(p, c, 29950 + s) for c in NEIGHBOURS for s in range(seeds)]
        else:
            out += [(p, "control", 30000 + s) for s in range(controls)]
    return out


#: catalogue look-alikes of the rate-history shapes, with the shape parameters tried (the closest wins)
LOOKALIKES = {"bias_ramp": [{}], "sf_asymmetry": [{}], "sf_nonlinearity_quadratic": [{}],
              "warmup_transient": [{"tau_s": float(t)} for t in np.geomspace(60.0, 3000.0, 12)]}


def separation(pname: str, snr: float = 10.0) -> None:
    """Each unknown's whitened, base-projected binned shape at ``snr``: the SNR left once its closest
    catalogue look-alike is fitted (the design separation d; the true noise, no analysis)."""
    prof = profile(pname)
    nominal = scenarios.nominal_model()
    base = scenarios.true_base(nominal)
    bins = make_bins(prof.t_s, prof.fs_hz, max_bins=1000)
    builder = DesignBuilder(prof.inputs, bins)
    whitener = Whitener(NoiseModel.of_model(nominal).bin_covariance(bins.centre_s, bins.width_s,
                                                                    bins.samples_per_bin, prof.fs_hz))
    fit = gls_fit(builder, whitener, bins.mean(builder.rate_dph(base)), base)

    def unit(binned: np.ndarray) -> np.ndarray:
        w = whitener.white(binned)
        w = w - fit.basis @ (fit.basis.T @ w)
        return w / np.linalg.norm(w)

    for case, shape in UNKNOWN.items():
        u = unit(bins.mean(shape(prof)))
        left = {name: min(snr * np.sqrt(max(0.0, 1.0 - float(u @ unit(
            builder.extra_columns(base, placeholder_spec(name, sh))[1][:, 0])) ** 2)) for sh in shapes)
            for name, shapes in LOOKALIKES.items()}
        name = min(left, key=left.get)
        print(f"| {pname} | {case.replace('|', chr(92) + '|')} | {name} | {left[name]:.1f} |")


def null_alpha(pname: str, draws: int, n_null: int = 300, alpha: float = 0.02) -> None:
    """The probes' false alarms on effect-free whitened residuals, by the workflow's own null machinery.

    One call of ``all_probes`` with ``n_null`` + ``draws`` standard-normal whitened columns: each
    probe's null scores on the first ``n_null`` give its threshold (as in a run), its scores on
    the rest stand for effect-free records (what the refit leaves of them under the true noise).
    Counts: a rate-history probe above its own threshold, and the adequacy family (every probe's
    best score against the family-wise threshold, ``adequacy.family_threshold``) with and without them.
    """
    prof = profile(pname)
    nominal = scenarios.nominal_model()
    base = scenarios.true_base(nominal)
    bins = make_bins(prof.t_s, prof.fs_hz, max_bins=1000)
    builder = DesignBuilder(prof.inputs, bins)
    whitener = Whitener(NoiseModel.of_model(nominal).bin_covariance(bins.centre_s, bins.width_s,
                                                                    bins.samples_per_bin, prof.fs_hz))
    fit = gls_fit(builder, whitener, bins.mean(builder.rate_dph(base)), base)
    x = ProbeInputs(prof.t_s, prof.table_rate_dps, prof.chamber_temp_c, np.zeros_like(prof.t_s),
                    bins=bins, reference_temp_c=nominal.reference_temp_c)
    z = np.random.default_rng(2029).standard_normal((bins.n_bins, n_null + draws))
    probes = all_probes(fit, whitener, bins, x, z, alpha)
    rate_history = (ProbeKind.SPIN_HEAT, ProbeKind.NET_TURNS)   # here: the tool also runs the code before them

    def alarms(chosen: list) -> np.ndarray:
        null = np.vstack([p.null[:n_null] for p in chosen]).max(axis=0)
        data = np.vstack([p.null[n_null:] for p in chosen]).max(axis=0)
        return data > order_statistic_quantile(null, 1.0 - alpha)

    each = {p.kind: p.null[n_null:] > order_statistic_quantile(p.null[:n_null], 1.0 - alpha)
            for p in probes if p.kind in rate_history}
    own = np.any(np.vstack(list(each.values())), axis=0)
    with_all = alarms(probes)
    without = alarms([p for p in probes if p.kind not in rate_history])
    print(f"| {pname} | {draws} | {' / '.join(str(v.sum()) for v in each.values())} | {own.sum()} | "
          f"{with_all.sum()} | {without.sum()} | "
          f"{(with_all & ~without).sum()} |")


def table(path: str) -> None:
    rows: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for line in Path(path).read_text().splitlines():
        r = json.loads(line)
        rows[(r["profile"], r["case"])].append(r)
    print("| profile | case | runs | named first | unexplained | where names the probe | "
          "claims ≥ 0.8 | what was named | median CPU s |\n|---|---|---|---|---|---|---|---|---|")
    for (p, case), rs in rows.items():
        word = next((w for k, w in WORDS.items() if k in case), None)
        first = (sum(bool(r["found"]) and r["found"][0][0] == case for r in rs)
                 if case in NEIGHBOURS else "–")
        where = sum(word in r["where"] for r in rs) if word else (
            sum(any(w in r["where"] for w in WORDS.values()) for r in rs))
        high = sum(any(pr >= 0.8 and n != case for n, pr in r["found"]) for r in rs)
        named = ", ".join(sorted({f"{n} {pr:.2f}" for r in rs for n, pr in r["found"]})) or "–"
        print(f"| {p} | {case.replace('|', chr(92) + '|')} | {len(rs)} | {first} | "
              f"{sum(r['unexplained'] for r in rs)} | {where} | {high} | {named[:120]} | "
              f"{np.median([r['cpu_s'] for r in rs]):.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--group", choices=("unknown", "neighbour", "control"), default="unknown")
    parser.add_argument("--profiles", default="P1,Q1,Q2")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--controls", type=int, default=100)
    parser.add_argument("--out", default="")
    parser.add_argument("--table", default="", help="print the Markdown rows of a JSON-lines file and stop")
    parser.add_argument("--separation", action="store_true",
                        help="print each unknown's SNR left after its closest catalogue look-alike and stop")
    parser.add_argument("--null-draws", type=int, default=0,
                        help="count the probes' false alarms on this many effect-free whitened draws and stop")
    args = parser.parse_args()
    if args.null_draws:
        for pname in args.profiles.split(","):
            null_alpha(pname, args.null_draws)
        return
    if args.table:
        table(args.table)
        return
    if args.separation:
        for pname in args.profiles.split(","):
            separation(pname)
        return
    with open(args.out or "/dev/stdout", "a", encoding="utf-8") as out:
        for pname, case, seed in jobs(args.group, args.profiles.split(","), args.seeds, args.controls):
            out.write(json.dumps(run(pname, case, seed)) + "\n")
            out.flush()


if __name__ == "__main__":
    main()
