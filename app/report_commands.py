"""``gyrocal report | verify | analyze allan``: wiring, not logic.

Exit codes follow interfaces.md: 0 ok, 1 an acceptance limit or a hash
failed, 2 bad input (RunFolderError / LogFormatError are mapped by the CLI).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrocal.analysis.allan import filtering as af
from gyrocal.analysis.allan.sources import open_record
from gyrocal.analysis.allan.summary import allan_curve_streamed, curve_json, fit_curve
from gyrocal.analysis.environment.interference import compare
from gyrocal.analysis.measured_log import LogFormatError
from gyrocal.app.keys import report_signer
from gyrocal.app.verdict import print_verdict
from gyrocal.errors import EXIT_ACCEPTANCE_FAILED, EXIT_OK, BadInput
from gyrocal.models.noise_terms import FIT_KEYS
from gyrocal.models.rate_units import output_to_dph
from gyrocal.record.ledger import LedgerError, check_against, read_ledger
from gyrocal.record.locks import run_folder_lock
from gyrocal.record.run_folder import JOURNAL, RunFolderError
from gyrocal.reports.build import HTML_FILE, build_report
from gyrocal.reports.certificate import Approval, certify_run
from gyrocal.reports.verify import verify_run_folder

#: Factor from each ``--units`` to deg/h.


def cmd_report(args: argparse.Namespace) -> int:

    # The folder's lock: a report rebuilt while a controller writes the folder would
    # append to its journal from a second process and break the hash chain.
    with run_folder_lock(args.run_dir):
        results = build_report(Path(args.run_dir),
                               signer=report_signer(Path(args.run_dir), args.signing_key))
    print(f"report: {Path(args.run_dir) / HTML_FILE}")
    for note in results.get("notes", []):
        print(f"  note: {note}")
    return print_verdict(results)


def cmd_certificate(args: argparse.Namespace) -> int:
    """``gyrocal certificate RUN_DIR``: report/certificate.pdf from report/results.json."""


    approval = Approval(args.approved_by, args.role, dt.date.today())
    run_dir = Path(args.run_dir)
    if not (run_dir / "report" / "results.json").is_file():

        raise RunFolderError(f"{run_dir / 'report' / 'results.json'}: missing; run "
                             f"`gyrocal report {run_dir}` first")
    # The folder's lock, as for a report rebuild: the certificate joins the journal.
    with run_folder_lock(run_dir):
        path, number, overall = certify_run(
            run_dir, customer=args.customer, approval=approval, number=args.number,
            out=Path(args.out) if args.out else None,
            signer=report_signer(run_dir, getattr(args, "signing_key", None)))
    print(f"certificate {number}: {path} (recorded in {run_dir / 'journal.jsonl'})")
    print(f"  statement of conformity: {overall}")
    return EXIT_OK


def cmd_verify(args: argparse.Namespace) -> int:
    result = verify_run_folder(Path(args.run_dir), public_key=args.key, ledger=args.ledger)
    if not result.ok:
        print(f"gyrocal verify: FAILED: {result.failure}", file=sys.stderr)
        return EXIT_ACCEPTANCE_FAILED
    print(result.summary())
    return EXIT_OK


def cmd_ledger(args: argparse.Namespace) -> int:
    """``gyrocal ledger FILE``: every run the station sealed is still where and what it was."""

    ledger = Path(args.ledger)
    try:
        entries = read_ledger(ledger)
    except LedgerError as exc:
        print(f"gyrocal ledger: FAILED: {exc}", file=sys.stderr)
        return EXIT_ACCEPTANCE_FAILED
    bad = 0
    for run_id, entry in entries.items():
        difference = check_against(entry, entry.run_dir / JOURNAL, ledger)
        bad += difference is not None
        print(f"{'CHANGED' if difference else 'OK'}  {run_id}  {entry.run_dir}"
              + (f"\n    {difference}" if difference else ""))
    print(f"{len(entries) - bad} of {len(entries)} runs end where the ledger says"
          + ("" if not bad else f"; {bad} missing, cut, extended or replaced"))
    return EXIT_ACCEPTANCE_FAILED if bad else EXIT_OK


def cmd_analyze_allan(args: argparse.Namespace) -> int:
    if not (args.scale_factor > 0 and math.isfinite(args.scale_factor)):
        raise BadInput(f"--scale-factor: must be a positive number, got {args.scale_factor!r}")
    if args.rate_hz is not None and not (args.rate_hz > 0 and math.isfinite(args.rate_hz)):
        raise BadInput(f"--rate-hz: must be a positive number, got {args.rate_hz!r}")
    record = open_record(args.log, args.column, args.rate_hz)
    to_dph = float(output_to_dph(1.0, args.scale_factor, args.units))

    def rate_dph():
        for block in record.blocks():
            yield block * to_dph

    try:
        curve = allan_curve_streamed(rate_dph, record.n_samples, record.rate_hz,
                                     tmp_dir=args.tmp_dir)
        fit = fit_curve(curve)
    except ValueError as exc:
        if isinstance(exc, LogFormatError):
            raise
        raise BadInput(f"{record.description}: column {record.column}: {exc}") from None
    print(f"Allan deviation of {record.description}, column {record.column} ÷ "
          f"{args.scale_factor:g}, from {args.units} to deg/h: {curve.n_samples} samples at "
          f"{record.rate_hz:g} Hz ({curve.n_samples / record.rate_hz:.6g} s); {curve.method}")
    print(f"  {'tau_s':>12} {'adev_dph':>12} {'lo_dph':>12} {'hi_dph':>12}")
    shown = np.unique(np.linspace(0, curve.tau_s.size - 1, min(15, curve.tau_s.size)).astype(int))
    for i in shown:
        print(f"  {curve.tau_s[i]:12.5g} {curve.adev[i]:12.5g} {curve.adev_lo[i]:12.5g} "
              f"{curve.adev_hi[i]:12.5g}")
    for name in FIT_KEYS:
        term = getattr(fit, name)
        print(f"  {name:>14} = {term.value:.5g}  (68 %: {term.lo:.4g} … {term.hi:.4g})")
    if fit.markov is not None:
        print(f"  {'markov':>14} : sigma {fit.markov.sigma_dph.value:.5g} deg/h, "
              f"tau {fit.markov.tau_s.value:.5g} s")
    else:
        print(f"  {'markov':>14} : none (not significant)")
    document = curve_json(curve, fit)
    if args.filter:
        document["filter"] = _filter_comparison(args, record, rate_dph, fit)
    if args.json_out:
        out = Path(args.json_out)
        out.write_text(json.dumps(document, indent=2, allow_nan=False) + "\n")
        print(f"wrote {out}")
    return EXIT_OK


def _filter_comparison(args: argparse.Namespace, record, rate_dph, before) -> dict:
    """``--filter``: the record filtered (analysis/allan/filtering.py), its terms against ``before``."""

    try:
        tuning = af.tune(af.FilterKind(args.filter), af.difference_variance(rate_dph),
                         record.rate_hz, args.filter_tau_s, args.forgetting)
        n_after = record.n_samples - tuning.dropped_samples
        after_curve = allan_curve_streamed(af.filtered_blocks(rate_dph, tuning), n_after,
                                           record.rate_hz, tmp_dir=args.tmp_dir)
        after = fit_curve(after_curve)
    except ValueError as exc:
        raise BadInput(f"{record.description}: --filter {args.filter}: {exc}") from None
    print(f"Filtered: {tuning.describe()}")
    print("  (a diagnostic of the filter: the log and any calibration are left as they are)")
    print(f"  {'term':>14} {'before':>12} {'after':>12} {'reduced by':>11}")
    reductions = {}
    for name in FIT_KEYS:
        b, a = getattr(before, name).value, getattr(after, name).value
        reductions[name] = af.reduction_pct(b, a)
        pct = "n/a (0)" if reductions[name] is None else f"{reductions[name]:.1f} %"
        if a > b:
            pct = "grew"
        print(f"  {name:>14} {b:12.5g} {a:12.5g} {pct:>11}")
    if any(getattr(after, n).value > getattr(before, n).value for n in FIT_KEYS):
        print(f"  note: a term that grew is the filter's own mark: below τ_f = {tuning.tau_s:g} s "
              "the smoothed record's Allan deviation rises as τ^+1/2, which the fit reads as rate "
              "random walk; judge the gyro's terms only at τ well above τ_f")
    return {"kind": str(tuning.kind), "model": tuning.describe(), "tau_s": tuning.tau_s,
            "q_dph2": tuning.q_dph2, "r_dph2": tuning.r_dph2, "steady_gain": tuning.gain,
            "forgetting": tuning.forgetting, "dropped_samples": tuning.dropped_samples,
            "after": curve_json(after_curve, after), "reduction_pct": reductions}


def cmd_analyze_interference(args: argparse.Namespace) -> int:
    """``gyrocal analyze interference POWERED OFF`` (analysis/environment/interference.py)."""

    if not (args.scale_factor > 0 and math.isfinite(args.scale_factor)):
        raise BadInput(f"--scale-factor: must be a positive number, got {args.scale_factor!r}")
    if not (args.drift_tau_s > 0 and math.isfinite(args.drift_tau_s)):
        raise BadInput(f"--drift-tau-s: must be a positive number, got {args.drift_tau_s!r}")
    to_dph = float(output_to_dph(1.0, args.scale_factor, args.units))
    records = [open_record([path], args.column, args.rate_hz) for path in (args.powered, args.off)]
    if records[0].rate_hz != records[1].rate_hz:
        raise BadInput(f"{records[1].description}: sampled at {records[1].rate_hz:g} Hz, the powered "
                       f"record at {records[0].rate_hz:g} Hz; compare records of one rate")
    data = [np.concatenate(list(r.blocks())) * to_dph for r in records]
    try:
        result = compare(data[0], data[1], records[0].rate_hz, args.drift_tau_s)
    except ValueError as exc:
        raise BadInput(f"{records[0].description}: {exc}") from None
    print(f"Table drive powered: {records[0].description}; off: {records[1].description}")
    print(f"  drift (std of {result.drift_tau_s:g} s means): powered {result.drift_powered_dph:.4g} "
          f"deg/h, off {result.drift_off_dph:.4g} deg/h; drift ratio {result.drift_ratio:.3g}")
    if not result.lines:
        print("  no spectral line stands out of the powered record")
    for line in result.lines:
        harmonic = f" (harmonic {line.harmonic} of the lowest)" if line.harmonic else ""
        print(f"  line {line.frequency_hz:.4f} Hz: {line.amplitude_dph:.4g} deg/h 0-to-peak "
              f"powered, {line.amplitude_off_dph:.3g} deg/h off{harmonic}")
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(result.to_json(), indent=2) + "\n")
        print(f"wrote {args.json_out}")
    return EXIT_OK
