"""``gyrocal report | verify | analyze allan``: wiring, not logic.

Exit codes follow interfaces.md: 0 ok, 1 an acceptance limit or a hash
failed, 2 bad input (RunFolderError / LogFormatError are mapped by the CLI).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrocal.cli import EXIT_ACCEPTANCE_FAILED, EXIT_OK

#: Factor from each ``--units`` to deg/h.
TO_DPH = {"deg/s": 3600.0, "deg/h": 1.0, "rad/s": math.degrees(1.0) * 3600.0}
_GAP_FACTOR = 1.5


def cmd_report(args: argparse.Namespace) -> int:
    from gyrocal.reports.build import HTML_FILE, build_report

    results = build_report(Path(args.run_dir))
    print(f"report: {Path(args.run_dir) / HTML_FILE}")
    for note in results.get("notes", []):
        print(f"  note: {note}")
    return _print_acceptance(results.get("acceptance", []))


def _print_acceptance(acceptance: list[dict]) -> int:
    for item in acceptance:
        verdict = "PASS" if item["pass"] else "FAIL"
        value = "not computed" if item["value"] is None else f"{item['value']:.6g}"
        print(f"  {verdict}  {item['name']}: {value} ({item['kind']} {item['limit']:.6g})")
    return EXIT_ACCEPTANCE_FAILED if any(not a["pass"] for a in acceptance) else EXIT_OK


def cmd_verify(args: argparse.Namespace) -> int:
    from gyrocal.reports.verify import verify_run_folder

    result = verify_run_folder(Path(args.run_dir))
    if not result.ok:
        print(f"gyrocal verify: MISMATCH: {result.failure}", file=sys.stderr)
        return EXIT_ACCEPTANCE_FAILED
    print(result.summary())
    return EXIT_OK


def _allan_input(log, column: str) -> tuple[np.ndarray, float, str]:
    """The samples to analyse, their rate and a description.

    A run folder holds holds and dwells at several temperatures back to back;
    its Allan record is the longest static/allan hold (as in the report).
    A plain log is used whole but must be evenly sampled.
    """
    from gyrocal.reports.measured_log import LogFormatError

    values = getattr(log, column, None) if column in log.__dataclass_fields__ else None
    if column in ("source", "segment", "extra") or values is None:
        available = [n for n in ("gyro", "table_rate_dps", "chamber_temp_c", "sensor_temp_c",
                                 "table_angle_deg") if getattr(log, n) is not None]
        raise LogFormatError(f"{log.source}: column {column!r} not in the log; "
                             f"available: {', '.join(available)}")
    values = np.asarray(values, dtype=float)
    if log.segment is not None:
        labels, counts = np.unique(log.segment, return_counts=True)
        holds = _hold_steps(Path(log.source))
        candidates = [(c, lab) for lab, c in zip(labels, counts, strict=True) if lab in holds]
        if not candidates:
            raise LogFormatError(f"{log.source}: no completed static or allan hold to analyse")
        _, label = max(candidates)
        mask = log.segment == label
        fs_hz = float(1.0 / np.median(np.diff(log.t_s[mask])))
        return values[mask], fs_hz, f"{log.source} step {label}"
    dt = np.diff(log.t_s)
    median = float(np.median(dt))
    gaps = np.flatnonzero(dt > _GAP_FACTOR * median)
    if gaps.size:
        row = int(gaps[0]) + 1
        raise LogFormatError(
            f"{log.source}: row {row + 1}: column t_s: gap of {dt[gaps[0]]:.6g} s after "
            f"{float(log.t_s[row - 1])!r} (median spacing {median:.6g} s, {gaps.size} gap(s)); "
            "the Allan deviation needs evenly spaced samples")
    return values, 1.0 / median, log.source


def _hold_steps(run_dir: Path) -> set[str]:
    from gyrocal.orchestrator.plan_record import read_plan_record

    try:
        steps = read_plan_record(run_dir).get("steps", [])
    except (OSError, ValueError):
        return set()
    return {s["step_id"] for s in steps if s.get("kind") in ("static", "allan")}


def cmd_analyze_allan(args: argparse.Namespace) -> int:
    from gyrocal.cli import BadInput
    from gyrocal.reports.allan_summary import allan_curve, curve_json, fit_curve
    from gyrocal.reports.measured_log import read_measured_log

    if not (args.scale_factor > 0 and math.isfinite(args.scale_factor)):
        raise BadInput(f"--scale-factor: must be a positive number, got {args.scale_factor!r}")
    log = read_measured_log(args.log)
    values, fs_hz, described = _allan_input(log, args.column)
    rate_dph = values / args.scale_factor * TO_DPH[args.units]
    try:
        curve = allan_curve(rate_dph, fs_hz)
        fit = fit_curve(curve)
    except ValueError as exc:
        raise BadInput(f"{described}: column {args.column}: {exc}") from None
    print(f"Allan deviation of {described}, column {args.column} ÷ {args.scale_factor:g}, "
          f"from {args.units} to deg/h: {rate_dph.size} samples at {fs_hz:g} Hz "
          f"({rate_dph.size / fs_hz:.6g} s); {curve.method}")
    print(f"  {'tau_s':>12} {'adev_dph':>12} {'lo_dph':>12} {'hi_dph':>12}")
    shown = np.unique(np.linspace(0, curve.tau_s.size - 1, min(15, curve.tau_s.size)).astype(int))
    for i in shown:
        print(f"  {curve.tau_s[i]:12.5g} {curve.adev[i]:12.5g} {curve.adev_lo[i]:12.5g} "
              f"{curve.adev_hi[i]:12.5g}")
    for name in ("Q_arcsec", "N_deg_per_rth", "B_dph", "K_dph_per_rth", "R_dph_per_h"):
        term = getattr(fit, name)
        print(f"  {name:>14} = {term.value:.5g}  (68 %: {term.lo:.4g} … {term.hi:.4g})")
    if fit.markov is not None:
        print(f"  {'markov':>14} : sigma {fit.markov.sigma_dph.value:.5g} deg/h, "
              f"tau {fit.markov.tau_s.value:.5g} s")
    else:
        print(f"  {'markov':>14} : none (not significant)")
    if args.json_out:
        out = Path(args.json_out)
        out.write_text(json.dumps(curve_json(curve, fit), indent=2, allow_nan=False) + "\n")
        print(f"wrote {out}")
    return EXIT_OK
