"""``gyrocal runs index|list``, ``gyrocal history``, ``gyrocal compare``: wiring, not logic."""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrocal.errors import BadInput
from gyrocal.reports.runs import database
from gyrocal.reports.runs.compare import compare_plot, compare_table, load_results
from gyrocal.reports.runs.history import history_plot, history_table, trends


def _bad_input(exc: Exception) -> int:
    raise BadInput(str(exc)) from None


def cmd_runs_index(args: argparse.Namespace) -> int:
    try:
        summary = database.index_runs(Path(args.db), [Path(d) for d in args.dirs])
    except database.RunsDatabaseError as exc:
        return _bad_input(exc)
    print(f"{args.db}: {summary.indexed} runs indexed ({summary.with_results} with results), "
          f"{summary.chunks} sample chunks reachable as the `samples` view")
    return 0


def cmd_runs_list(args: argparse.Namespace) -> int:
    try:
        rows = database.list_runs(Path(args.db))
    except database.RunsDatabaseError as exc:
        return _bad_input(exc)
    print(f"{'run id':<24} {'serial':<12} {'state':<10} {'started (UTC)':<20} results  procedure")
    for run_id, serial, procedure, state, started, has_results, _run_dir in rows:
        when = "-" if started is None else started.strftime("%Y-%m-%d %H:%M:%S")
        print(f"{run_id:<24} {serial:<12} {state:<10} {when:<20} "
              f"{'yes' if has_results else 'no':<8} {procedure}")
    return 0


def cmd_history(args: argparse.Namespace) -> int:
    try:
        model, metrics, runs = database.history(Path(args.db), args.serial, args.model)
    except database.RunsDatabaseError as exc:
        return _bad_input(exc)
    if not runs:
        return _bad_input(ValueError(f"{args.serial}: no calibrated runs in {args.db} "
                                     "(`gyrocal runs list` shows what is indexed)"))
    series = trends(metrics, runs)
    unit = f"{model} {args.serial}".strip()
    print(history_table(unit, series))
    plot = history_plot(unit, series, Path(args.plot or f"history-{args.serial}.png"))
    print(f"trend plot: {plot}")
    drifted = sorted({name for name, points in series.items() for p in points if p.drift})
    print("drift beyond uncertainty: " + (", ".join(drifted) if drifted else "none"))
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    try:
        dirs = [database.run_dir_of(Path(args.db), run) for run in (args.run_a, args.run_b)]
        a, b = (load_results(d) for d in dirs)
    except database.RunsDatabaseError as exc:
        return _bad_input(exc)
    labels = [str((r.get("run") or {}).get("run_id") or d.name) for r, d in zip((a, b), dirs,
                                                                               strict=True)]
    print(compare_table(a, b, *labels))
    plot = compare_plot(a, b, *labels, Path(args.plot or "compare.png"))
    print(f"overlay plots: {plot}")
    return 0
