"""The ``gyrocal`` command: argument parsing, exit codes, and error presentation.

Exit codes (interfaces.md): 0 success · 1 acceptance failed · 2 bad input ·
3 instrument or run fault. Bad input and instrument faults print one clear
message, never a traceback (``--debug`` shows it). Each sub-command's work
lives in its own module; this file only routes.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from gyrocal import __version__
from gyrocal.app.heap import large_arrays_on_heap
from gyrocal.errors import (  # noqa: F401 - re-exported: the names scripts already import
    EXIT_ACCEPTANCE_FAILED,
    EXIT_BAD_INPUT,
    EXIT_FAULT,
    EXIT_OK,
    NO_ROOM_ERRNOS,
    BadInput,
    RunFaultError,
)
from gyrocal.instruments.errors import InstrumentError
from gyrocal.record.locks import LockBusyError

#: Bad input (exit 2): our one base, which every input error subclasses, and the OS's own
#: answers for a path that names nothing or the wrong kind of thing.
BAD_INPUT_TYPES: tuple[type[BaseException], ...] = (
    BadInput, FileNotFoundError, IsADirectoryError, NotADirectoryError)


#: Faults (exit 3): the rig was left safe, the run is resumable.
FAULT_TYPES: tuple[type[BaseException], ...] = (RunFaultError, InstrumentError, LockBusyError)


#: The lab's runs database, in the working folder unless ``--db`` names another.
RUNS_DB = "runs.duckdb"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gyrocal", description=__doc__.splitlines()[0])
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--version", action="version", version=f"gyrocal {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run_commands(sub)
    _add_live_commands(sub)
    _add_report_commands(sub)
    _add_runs_commands(sub)
    _add_analyze_commands(sub)
    _add_instrument_commands(sub)
    return parser


def _add_run_commands(sub: argparse._SubParsersAction) -> None:
    """Validate, plan, run, resume: running a procedure."""
    p = sub.add_parser("validate", help="validate a procedure (and station) before anything moves")
    p.add_argument("procedure")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--station")
    group.add_argument("--sim", action="store_true",
                       help="check as for `run --sim` (the simulated gyro takes the procedure's rate)")
    _add_allow_outside_paths(p)
    p.set_defaults(func=_lazy("gyrocal.app.run_commands", "cmd_validate"))

    p = sub.add_parser("plan", help="print the expanded steps, durations and ETA")
    p.add_argument("procedure")
    p.add_argument("--station")
    _add_allow_outside_paths(p)
    p.set_defaults(func=_lazy("gyrocal.app.run_commands", "cmd_plan"))

    p = sub.add_parser("run", help="run a procedure on a station or against simulated instruments")
    p.add_argument("procedure")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--station")
    group.add_argument("--sim", action="store_true", help="start simulated instruments on loopback")
    p.add_argument("--out", help="run folder (default runs/<run id>)")
    p.add_argument("--speed", default=None, help="X (real time × X) or max (simulated time; default with --sim)")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--operator", default=None)
    p.add_argument("--sim-station", default=None,
                   help="with --sim: simulate this station instead of the procedure's")
    p.add_argument("--inject", action="append", metavar="SPEC",
                   help="with --sim: arm a simulator fault, ROLE.FAULT[:COUNT|:always]"
                        "[:key=value…][@STEP], e.g. chamber.no_reply:3@T02.soak (repeatable)")
    p.add_argument("--signing-key", default=None,
                   help="the station's private key (default: the station file's signing_key, "
                   "or $GYROCAL_SIGNING_KEY)")
    _add_allow_outside_paths(p)
    p.set_defaults(func=_lazy("gyrocal.app.run_commands", "cmd_run"))

    p = sub.add_parser("resume", help="continue a faulted or interrupted run")
    p.add_argument("run_dir")
    p.add_argument("--speed", default=None)
    p.add_argument("--signing-key", default=None, help="as for run")
    p.set_defaults(func=_lazy("gyrocal.app.run_commands", "cmd_resume"))


def _add_allow_outside_paths(p: argparse.ArgumentParser) -> None:
    p.add_argument("--allow-outside-paths", action="store_true",
                   help="let the procedure/station name files outside their folder, project "
                        "and the working folder")


def _add_live_commands(sub: argparse._SubParsersAction) -> None:
    """Status, watch, confirm: following and answering a run under way."""
    p = sub.add_parser("status", help="where a run is (state, step n/N, ETA, last event, holder)")
    p.add_argument("run_dir")
    p.add_argument("--json", action="store_true", help="the same snapshot as JSON, for scripts")
    p.set_defaults(func=_lazy("gyrocal.app.watch.status", "cmd_status"))

    p = sub.add_parser("watch", help="a read-only live page for a run (from its folder)")
    p.add_argument("run_dir")
    p.add_argument("--port", type=int, default=8765, help="0: any free port")
    p.add_argument("--bind", default="127.0.0.1",
                   help="address to serve on; anything but loopback requires the printed token")
    p.set_defaults(func=_lazy("gyrocal.app.watch.server", "cmd_watch"))

    p = sub.add_parser("confirm", help="tell a waiting run the operator has done what it asked "
                       "(a remount of the IMU fixture)")
    p.add_argument("run_dir")
    p.add_argument("--mounting", default=None,
                   help="the mounting done (as named in the procedure); checked by the run")
    p.set_defaults(func=_lazy("gyrocal.app.run_commands", "cmd_confirm"))


def _add_report_commands(sub: argparse._SubParsersAction) -> None:
    """Report, certificate, verify, ledger, keys: the report and its audit."""
    p = sub.add_parser("report", help="(re)build RUN_DIR/report/")
    p.add_argument("run_dir")
    p.add_argument("--signing-key", default=None, help="seal the rebuilt report (as for run)")
    p.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_report"))

    p = sub.add_parser("certificate", help="RUN_DIR/report/certificate.pdf (ISO/IEC 17025 §7.8) "
                                           "from its results.json")
    p.add_argument("run_dir")
    p.add_argument("--customer", default="(customer not stated)", help="who the calibration is for")
    p.add_argument("--number", default=None, help="certificate number (default GC-<run id>)")
    p.add_argument("--approved-by", default="(not yet approved)",
                   help="name of the person authorising the certificate")
    p.add_argument("--role", default="(role not stated)", help="their role, e.g. Quality manager")
    p.add_argument("--out", default=None, help="PDF path (default RUN_DIR/report/certificate.pdf)")
    p.add_argument("--signing-key", default=None,
                   help="seal the certificate's journal line (as for report)")
    p.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_certificate"))

    p = sub.add_parser("verify", help="audit: completeness, every hash, the numbers, the signature")
    p.add_argument("run_dir")
    p.add_argument("--key", default=None,
                   help="the station's public key (PEM): check authenticity, not only integrity")
    p.add_argument("--ledger", default=None,
                   help="the station ledger (beside its key): the run must end where it says")
    p.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_verify"))

    p = sub.add_parser("ledger", help="audit the station ledger: every sealed run still there "
                       "and unchanged")
    p.add_argument("ledger", help="e.g. /secure/station-keys/station.ledger.jsonl")
    p.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_ledger"))

    p = sub.add_parser("keys", help="generate the station's Ed25519 signing key pair")
    p.add_argument("--out", default="keys", help="folder for NAME.key (mode 0600) and NAME.pub")
    p.add_argument("--name", default="station")
    p.set_defaults(func=_lazy("gyrocal.app.keys", "cmd_keys"))


def _add_runs_commands(sub: argparse._SubParsersAction) -> None:
    """Runs, history, compare: every run of a gyro as a database."""
    p = sub.add_parser("runs", help="the lab's runs as a DuckDB database (index, list)")
    rsub = p.add_subparsers(dest="runs_command", required=True, metavar="RUNS_COMMAND")
    r = rsub.add_parser("index", help="add or update run folders (found under each DIR)")
    r.add_argument("dirs", nargs="+", metavar="DIR")
    r.add_argument("--db", default=RUNS_DB)
    r.set_defaults(func=_lazy("gyrocal.app.runs_commands", "cmd_runs_index"))
    r = rsub.add_parser("list", help="the indexed runs")
    r.add_argument("--db", default=RUNS_DB)
    r.set_defaults(func=_lazy("gyrocal.app.runs_commands", "cmd_runs_list"))

    p = sub.add_parser("history", help="one unit (serial, and model when several share it) "
                       "across its calibrations: table and trend plot")
    p.add_argument("serial")
    p.add_argument("--model", default=None,
                   help="the unit's model, when units of several models share the serial")
    p.add_argument("--db", default=RUNS_DB)
    p.add_argument("--plot", default=None, help="PNG path (default history-SERIAL.png)")
    p.set_defaults(func=_lazy("gyrocal.app.runs_commands", "cmd_history"))

    p = sub.add_parser("compare", help="two runs side by side, with overlay plots")
    p.add_argument("run_a", help="a run folder or an indexed run id")
    p.add_argument("run_b")
    p.add_argument("--db", default=RUNS_DB)
    p.add_argument("--plot", default=None, help="PNG path (default compare.png)")
    p.set_defaults(func=_lazy("gyrocal.app.runs_commands", "cmd_compare"))


def _add_analyze_commands(sub: argparse._SubParsersAction) -> None:
    """Analyze allan | interference, discrepancy: analyses of measured logs."""
    p = sub.add_parser("analyze", help="analyse a measured log")
    asub = p.add_subparsers(dest="analysis", required=True, metavar="ANALYSIS")
    a = asub.add_parser("allan", help="Allan deviation and noise terms of a log",
                        description="Exact overlapping Allan deviation, streamed in bounded "
                        "memory: one run folder (its longest static hold), or one or more CSV/"
                        "Parquet logs in time order (the spec's log, or any time+rate export).")
    a.add_argument("log", nargs="+", help="a run folder, or log files in time order")
    a.add_argument("--column", default=None,
                   help="the rate column (default: gyro, else a common rate name, else the "
                   "only non-time column)")
    a.add_argument("--rate-hz", type=float, default=None,
                   help="sample rate, for logs without a time column")
    a.add_argument("--tmp-dir", default=None,
                   help="where a long record's phase is spilled (default: the system's)")
    a.add_argument("--units", default="deg/s", choices=["deg/s", "deg/h", "rad/s"])
    a.add_argument("--scale-factor", type=float, default=1.0)
    a.add_argument("--json", dest="json_out")
    a.add_argument("--filter", choices=["kalman", "adaptive-kalman"], default=None,
                   help="also run this denoising filter over the record and report the Allan "
                   "terms before and after (a diagnostic: nothing is written back)")
    a.add_argument("--filter-tau-s", type=float, default=1.0,
                   help="the filter's time constant, s (sets its process noise q; default 1)")
    a.add_argument("--forgetting", type=float, default=0.999,
                   help="adaptive-kalman: the Sage-Husa forgetting factor b (default 0.999)")
    a.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_analyze_allan"))

    a = asub.add_parser("interference", help="table-induced interference: drive powered vs off",
                        description="Compares a static logged with the rate table's drive "
                        "powered and holding zero rate against one with the drive off: the "
                        "drift ratio and the spectral lines the drive adds (frequency, amplitude).")
    a.add_argument("powered", help="log (CSV/Parquet) or run folder: the drive powered, at rest")
    a.add_argument("off", help="log or run folder: the drive off (interlock open)")
    a.add_argument("--column", default=None, help="the rate column (as for analyze allan)")
    a.add_argument("--rate-hz", type=float, default=None,
                   help="sample rate, for logs without a time column")
    a.add_argument("--units", default="deg/s", choices=["deg/s", "deg/h", "rad/s"])
    a.add_argument("--scale-factor", type=float, default=1.0)
    a.add_argument("--drift-tau-s", type=float, default=1.0,
                   help="drift is the std of the records' means over this time (default 1 s)")
    a.add_argument("--json", dest="json_out")
    a.set_defaults(func=_lazy("gyrocal.app.report_commands", "cmd_analyze_interference"))

    p = sub.add_parser("discrepancy", help="find what the model lacks to explain the measured data")
    p.add_argument("--model", required=True)
    p.add_argument("--measured", required=True)
    p.add_argument("--out", default="discrepancy-out")
    p.add_argument("--seed", type=int, default=0)
    # 10 M-sample full-rate arrays: kept on the heap, not re-faulted per temporary (app/heap.py)
    p.set_defaults(func=_lazy("gyrocal.app.discrepancy_command", "cmd_discrepancy", large_arrays_on_heap))


def _add_instrument_commands(sub: argparse._SubParsersAction) -> None:
    """Decode, station check, sim serve, demo: instruments and captures."""
    p = sub.add_parser("decode", help="a gyro's recorded bytes as a measured log, with a summary",
                       description="Decode a raw capture from a unit (binary, or one decimal number "
                       "per byte): the datagram type and sample rate are read from the bytes.")
    p.add_argument("capture", help="the captured bytes (binary, or decimal text)")
    p.add_argument("--driver", required=True, help="the gyro's driver (stim300)")
    p.add_argument("--accelerometer-range-g", type=int, default=10, choices=(5, 10, 30, 80),
                   help="the unit's accelerometer range (sets the LSB; default 10)")
    p.add_argument("--rate-lsb", type=float, default=2.0**-14,
                   help="gyro output units per LSB (default 2**-14 deg/s)")
    p.add_argument("--axis", default="x", choices=("x", "y", "z"),
                   help="the unit under test's axis, logged as `gyro` (all three are logged)")
    p.add_argument("--table-rate-dps", type=float, default=0.0,
                   help="the rate the unit was turned at during the capture (default 0)")
    p.add_argument("--chamber-temp-c", type=float, default=None,
                   help="the ambient during the capture (default: the gyro's own temperature "
                   "where the datagram has it, else 23 °C, stated as assumed)")
    p.add_argument("--out", default=None, help="the measured log, .parquet or .csv")
    p.add_argument("--json", default=None, help="write the summary here as JSON")
    p.set_defaults(func=_lazy("gyrocal.app.decode_capture", "cmd_decode"))

    p = sub.add_parser("station", help="a station's instruments")
    ssub = p.add_subparsers(dest="station_command", required=True, metavar="STATION_COMMAND")
    s = ssub.add_parser("check", help="connect to each instrument, move nothing, report what a "
                                      "run relies on (exit 3 naming each problem)")
    s.add_argument("station", help="station file with the instruments' addresses")
    s.add_argument("--only", choices=("chamber", "table", "gyro", "supply"), default=None)
    s.add_argument("--json", default=None, metavar="OUT", help="write the report as JSON here")
    s.set_defaults(func=_lazy("gyrocal.app.station_check", "cmd_station_check"))

    p = sub.add_parser("sim", help="simulated instruments")
    ssub = p.add_subparsers(dest="sim_command", required=True, metavar="SIM_COMMAND")
    s = ssub.add_parser("serve", help="serve simulated instruments until Ctrl-C")
    s.add_argument("--station", default=None)
    s.add_argument("--speed", default="1", help="real time × X (default 1)")
    s.add_argument("--seed", type=int, default=None)
    s.add_argument("--write-station", default=None,
                   help="write the station file with the live addresses here")
    s.add_argument("--replay-gyro", default=None, metavar="CAPTURE",
                   help="serve this recorded capture (binary or decimal text) as the gyro, byte "
                   "for byte at its own rate, looped")
    s.add_argument("--unit-serial", default=None, metavar="SERIAL",
                   help="the serial the simulated STIM300 reports (N and 14 digits; default none)")
    s.set_defaults(func=_lazy("gyrocal.app.sim_serve", "cmd_sim_serve"))

    p = sub.add_parser("demo", help="the dry run against simulated instruments")
    p.add_argument("--out", default=None)
    p.set_defaults(func=_lazy("gyrocal.app.demo", "cmd_demo"))


def _version() -> str:
    return __version__


def _lazy(module: str, name: str,
          scope: Callable[[], contextlib.AbstractContextManager] = contextlib.nullcontext
          ) -> Callable[[argparse.Namespace], int]:
    """The handler ``module.name``, imported when its command runs: each command module pulls
    in its own heavy libraries (pandas, pyarrow, matplotlib, pymodbus), which ``--help`` and
    every other command need not pay for. A missing module or name is raised, never hidden.
    ``scope`` is entered before the import (app/heap.py's allocator settings must precede
    the threads pyarrow starts when it is imported)."""
    def call(args: argparse.Namespace) -> int:
        with scope():
            handler = getattr(importlib.import_module(module), name)
            return int(handler(args) or 0)

    call.__name__ = name
    return call


def _terminate(signum: int, frame: object) -> None:
    """SIGTERM before the engine installs its own handlers: the same path as Ctrl-C."""
    raise KeyboardInterrupt(f"signal {signum}")



def main(argv: Sequence[str] | None = None, *,
         on_sim_started: Callable[[Any], None] | None = None) -> int:
    """The command line. ``on_sim_started`` is called with each simulated station a dry run
    starts (before anything is commanded): how a test reaches the simulators it drives."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.on_sim_started = on_sim_started
    # Installed before anything is loaded or moved: a SIGTERM in the first
    # milliseconds ends as cleanly (exit 3, no traceback) as one during a run.
    # Only the main thread may install handlers (the engine makes the same
    # choice); a run driven from a thread, as the live-page test does, is
    # stopped by whoever owns that thread.
    if threading.current_thread() is not threading.main_thread():
        return _dispatch(args)
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _dispatch(args)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _dispatch(args: argparse.Namespace) -> int:
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("gyrocal: interrupted", file=sys.stderr)
        return EXIT_FAULT
    except Exception as exc:
        if args.debug:
            raise
        if isinstance(exc, OSError) and exc.errno in NO_ROOM_ERRNOS:
            print(f"gyrocal: fault: no room to write ({exc.strerror}: {exc.filename or 'a write'}); "
                  "nothing recorded is lost (every journal line is fsynced); free space, then "
                  "`gyrocal resume RUN_DIR` continues a run", file=sys.stderr)
            return EXIT_FAULT
        if isinstance(exc, BAD_INPUT_TYPES):
            print(f"gyrocal: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        if isinstance(exc, FAULT_TYPES):
            print(f"gyrocal: fault: {exc}", file=sys.stderr)
            return EXIT_FAULT
        # Never a traceback: a bug still ends with a clear line and the fault code.
        print(f"gyrocal: internal error: {type(exc).__name__}: {exc} "
              "(run again with --debug for the traceback)", file=sys.stderr)
        return EXIT_FAULT


def entry(argv: Sequence[str] | None = None) -> NoReturn:
    """The ``gyrocal`` program (console script and ``python -m gyrocal``): main, then exit.

    Once the command has its exit code, a Ctrl-C or SIGTERM while the interpreter
    shuts down (joining threads, flushing, finalising) would print
    "Exception ignored … KeyboardInterrupt" with a traceback. Nothing is left to
    protect by then (every journal line is fsynced, the command has returned),
    so such a signal ends the process at once with the command's own code.
    """
    try:
        code = main(argv)
    except KeyboardInterrupt:      # after the command's own handling, before main returned
        print("gyrocal: interrupted", file=sys.stderr)
        code = EXIT_FAULT
    if threading.current_thread() is threading.main_thread():
        def finish(signum: int, frame: object) -> None:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(code)

        signal.signal(signal.SIGINT, finish)
        signal.signal(signal.SIGTERM, finish)
    raise SystemExit(code)


if __name__ == "__main__":
    entry()
