"""``gyrocal validate | plan | run | resume | status | demo``: wiring, not logic.

Each command loads and validates its inputs (exit 2 on a problem), builds the
instruments — real ones from the station file, or ``--sim`` simulators on
loopback sharing one clock — and hands the plan to the engine. A resumed run
re-reads the procedure and station from where they were and refuses if they
changed since the run started (their SHA-256 is in the manifest).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import getpass
import json
import logging
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from gyrocal.app.discrepancy_command import run_discrepancy
from gyrocal.errors import EXIT_ACCEPTANCE_FAILED, EXIT_FAULT, EXIT_OK, BadInput
from gyrocal.instruments.driver_spec import Role
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.factory import Instruments, open_instruments
from gyrocal.instruments.registry import registry
from gyrocal.instruments.sim.fault_plan import FaultPlan, FaultSpecError, parse_injection
from gyrocal.instruments.sim.imu_source import FIXTURE_FAULTS
from gyrocal.instruments.sim.station_sim import SimulatedStation
from gyrocal.models.clock import RealClock, SimClock, make_clock
from gyrocal.orchestrator.doc_links import with_doc_links
from gyrocal.orchestrator.engine import EnginePolicy, RunEngine
from gyrocal.orchestrator.interrupts import ClosingSignals
from gyrocal.orchestrator.notify import Notifier
from gyrocal.orchestrator.plan import Plan, expand_plan, format_plan
from gyrocal.orchestrator.procedure import Procedure, load_procedure
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.remount import (
    FileConfirmOperator,
    SimulatedFixtureOperator,
    write_confirmation,
)
from gyrocal.orchestrator.retry_console import RetryConsole
from gyrocal.orchestrator.run_close import close_completed, steps_completed_run
from gyrocal.orchestrator.run_errors import RunFaultError
from gyrocal.orchestrator.station import Station, SupplyConfig, load_station
from gyrocal.orchestrator.station_fit import check_runnable, is_simulated
from gyrocal.orchestrator.unit_power import UnitPowerPolicy
from gyrocal.problems import ProcedureError
from gyrocal.record.journal import JournalEvent, sha256_file
from gyrocal.record.locks import (
    FileLock,
    LockBusyError,
    identity_locks,
    instrument_locks,
    run_folder_lock,
)
from gyrocal.record.plan_record import write_plan_record
from gyrocal.record.run_folder import IDENTITY_KEYS, RunFolder, new_run_id
from gyrocal.record.signing import (
    KeyPairFiles,
    Signer,
    fingerprint,
    generate_key_pair,
    load_public_key,
    signer_from,
)
from gyrocal.record.strays import set_aside
from gyrocal.reports.build import build_report
from gyrocal.reports.certificate import Approval, certify_run
from gyrocal.reports.verify import verify_run_folder
from gyrocal.units import format_hms

#: Called with each ``SimulatedStation`` right after ``--sim`` starts it, before any
#: driver connects (``gyrocal.cli.main(..., on_sim_started=)``). Fault-injection tests
#: arm simulator faults through it, so faults reach the very simulators a real
#: ``run``/``resume`` talks to. None in normal use.
SimStarted = Callable[[Any], None]


def quiet_library_logs(debug: bool = False) -> None:
    """pymodbus logs every retry to stderr; the journal is where retries belong."""
    level = logging.DEBUG if debug else logging.CRITICAL
    # the drivers' own retry warnings too: retries reach the console once, collapsed
    # (retry_console.py), and the journal in full
    for name in ("pymodbus", "pyvisa", "pyvisa_py", "gyrocal.instruments"):
        logging.getLogger(name).setLevel(level)


# -- validate / plan -----------------------------------------------------------------------

def cmd_validate(args: argparse.Namespace) -> int:
    """Everything ``run`` checks before anything moves, for the same station and ``--sim``.
    Each problem links the part of docs/reference/ that explains its key."""
    try:
        procedure = load_procedure(args.procedure, station_path=args.station,
                                   allow_outside=args.allow_outside_paths)
    except ProcedureError as error:
        raise with_doc_links(error, args.procedure) from None
    plan = expand_plan(procedure)
    # a station whose every address is `sim` can only run with --sim: judge it that way
    sim = args.sim or is_simulated(procedure)
    check_runnable(procedure, sim)
    # the key run would seal with, loaded as run loads it (missing, unreadable, readable by
    # others, not a key): validate OK must mean run accepts
    run_signer(None, procedure.station.signing_key)
    how = " for `gyrocal run --sim`" if sim else ""
    print(f"{procedure.file}: OK{how} — {procedure.name!r} on station {procedure.station.name!r}: "
          f"{len(plan.steps)} steps, ETA {format_hms(plan.total_s)} (worst case {format_hms(plan.max_total_s)})")
    return EXIT_OK


def cmd_plan(args: argparse.Namespace) -> int:
    procedure = load_procedure(args.procedure, station_path=args.station,
                               allow_outside=args.allow_outside_paths)
    print(format_plan(expand_plan(procedure)))
    return EXIT_OK


# -- run / resume --------------------------------------------------------------------------

def _policy(procedure: Procedure) -> EnginePolicy:
    quality = procedure.data_quality
    safe = procedure.station.chamber.safe_state
    return EnginePolicy(
        max_loss_fraction=quality.max_lost_frame_fraction,
        max_repeats=quality.max_step_repeats,
        safe_setpoint_c=safe.setpoint_c if safe.action == "setpoint" else None,
        read_timeout_margin_s=procedure.station.gyro.timeout_s,
        chamber_retries=procedure.station.chamber.retries,
        table_retries=procedure.station.table.retries,
        table_hold=procedure.station.table.holds_axis_when_safe,
        unit_power=_unit_power(procedure.station.supply),
    )


def _unit_power(supply: SupplyConfig | None) -> UnitPowerPolicy | None:
    if supply is None:
        return None
    return UnitPowerPolicy(supply.voltage_v, supply.current_limit_a, supply.unit_power_safe,
                           supply.retries)


@contextlib.contextmanager
def station_instruments(procedure: Procedure, clock, sim: bool, seed: int | None,
                        on_retry, on_sim_started: SimStarted | None = None
                        ) -> Iterator[tuple[Instruments, Any]]:
    """Instruments for the run: simulators on loopback (``sim``) or the station's addresses."""
    station = procedure.station
    fs_hz = procedure.defaults.sample_rate_hz
    check_runnable(procedure, sim)
    simulated = None
    try:
        addresses = None
        if sim:

            try:
                simulated = SimulatedStation(station, clock, seed=seed, sample_rate_hz=fs_hz).start()
            except ValueError as exc:
                raise BadInput(str(exc)) from None
            addresses = simulated.addresses
            if on_sim_started is not None:
                on_sim_started(simulated)
        instruments = open_instruments(station, clock, addresses, on_retry=on_retry,
                                       sample_rate_hz=fs_hz)
        try:
            with _identity_locks(instruments, sim):
                yield instruments, simulated
        finally:
            instruments.close()
    finally:
        if simulated is not None:
            simulated.stop()


def _input_files(procedure: Procedure) -> dict[str, Path]:
    files: dict[str, Path] = {}
    for path in procedure.files:
        role = "procedure" if path == procedure.path else (
            "station" if procedure.station.path and path == procedure.station.path else
            f"include-{path.stem}")
        files[role] = path
    sim = procedure.station.simulation
    if sim is not None:
        files["gyro_model"] = Path(sim.gyro_model)
    return files


def _fixture_operator(procedure: Procedure, folder: RunFolder, simulated: Any):
    """Who turns the IMU fixture at a remount: the simulated fixture, or a person."""
    if not procedure.mountings:
        return None
    if simulated is not None:
        if simulated.fixture is None:
            raise BadInput(f"{procedure.file}: mountings: the simulated station's gyro model is "
                           "single-axis; a multi-axis procedure needs a version-2 (IMU) model")
        return SimulatedFixtureOperator(simulated.fixture)
    return FileConfirmOperator(folder.path)


def cmd_confirm(args: argparse.Namespace) -> int:
    """``gyrocal confirm RUN_DIR``: the operator has done what the run asked (a remount)."""
    run_dir = Path(args.run_dir)
    if not (run_dir / "journal.jsonl").is_file():
        raise BadInput(f"{run_dir}: not a run folder (no journal.jsonl)")
    path = write_confirmation(run_dir, args.mounting)
    print(f"confirmed: {path}" + (f" (mounting {args.mounting})" if args.mounting else ""))
    return 0


def _clock_for(speed: str | None, sim: bool) -> RealClock | SimClock:
    try:
        return make_clock(speed if speed is not None else ("max" if sim else "1"))
    except ValueError as exc:
        raise BadInput(str(exc)) from None


def cmd_run(args: argparse.Namespace) -> int:
    quiet_library_logs(getattr(args, "debug", False))
    station_path = args.station
    if args.sim and args.sim_station:
        station_path = args.sim_station
    procedure = load_procedure(args.procedure, station_path=station_path,
                               allow_outside=args.allow_outside_paths)
    plan = expand_plan(procedure)
    check_runnable(procedure, args.sim)
    if not args.sim and args.speed not in (None, "1", "1.0"):
        # Real chambers and tables live in real time: a faster clock would cut soaks short.
        raise BadInput(f"--speed {args.speed}: only --sim runs can change the clock; "
                       "real instruments run at --speed 1")
    clock = _clock_for(args.speed, args.sim)
    fault_plan = _fault_plan(getattr(args, "inject", None) or [], args.sim, plan,
                             procedure.station)
    run_dir = Path(args.out) if args.out else Path("runs") / new_run_id()
    files = _input_files(procedure)
    with contextlib.ExitStack() as held:
        # The station's instruments first: a refused second run leaves no folder behind.
        held.enter_context(_station_locks(procedure, args.sim))
        folder = _create_folder(run_dir, procedure, plan, files, args)
        _announce_stale(held.enter_context(run_folder_lock(folder.path)))
        record = write_plan_record(folder.path, procedure, plan)
        folder.update_manifest(plan_sha256=sha256_file(record))
        print(f"run folder: {folder.path}", file=sys.stderr)
        signer = run_signer(getattr(args, "signing_key", None), procedure.station.signing_key)
        return _execute(folder, procedure, plan, clock, args.sim, args.seed, fault_plan, signer,
                        on_sim_started=args.on_sim_started)


def _station_locks(procedure: Procedure, sim: bool) -> contextlib.AbstractContextManager:
    """Exclusive locks on the station's instrument addresses (``--sim`` instruments are private)."""
    if sim:
        return contextlib.nullcontext([])
    station = procedure.station
    return instrument_locks({key.split(".")[0]: address
                             for key, address in station.addresses().items()})


@contextlib.contextmanager
def _identity_locks(instruments: Instruments, sim: bool) -> Iterator[None]:
    """Locks on the serials the chamber and the table report, before preflight commands them.

    The address locks already refused a second controller on any spelling of
    the same endpoint; this catches two endpoints of one instrument. The
    chamber first: its identity is register reads only, while the table's
    ``*IDN?`` opens a session (the dialect's start-up). ``--sim`` instruments
    are private to the run.
    """
    with contextlib.ExitStack() as held:
        if not sim:
            for instrument in (instruments.chamber, instruments.table):
                held.enter_context(identity_locks([instrument.identify()]))
        yield


def _announce_stale(lock: FileLock) -> None:
    if lock.stale is not None:
        print(f"gyrocal: note: {lock.what}: the previous controller ({lock.stale.describe()}) "
              "ended without releasing its lock (a crash); taking over", file=sys.stderr)


def _create_folder(run_dir: Path, procedure: Procedure, plan: Plan, files: dict[str, Path],
                   args: argparse.Namespace) -> RunFolder:
    return RunFolder.create(
        run_dir,
        procedure_path=files.pop("procedure"),
        station_path=files.pop("station", None),
        extra_files=files,
        manifest_fields={
            "mode": "sim" if args.sim else "station",
            "speed": args.speed if args.speed is not None else ("max" if args.sim else "1"),
            "seed": args.seed,
            "operator": args.operator or _operator(),
            "unit_under_test": {"model": procedure.unit_under_test.model,
                                "serial": procedure.unit_under_test.serial},
            "station_name": procedure.station.name,
            "steps": [step.step_id for step in plan.steps],
            "eta_s": plan.total_s,
            "pid": os.getpid(),
        },
    )


def _fault_plan(specs: list[str], sim: bool, plan: Plan, station: Station):
    """Parse ``--inject`` values (dry runs only) and check the steps they name exist.

    The fault names are those of the station's simulators (their driver specs).
    """
    if not specs:
        return None
    if not sim:
        raise BadInput("--inject arms faults in the simulators; it needs --sim")

    known: dict[str, tuple[str, ...]] = {
        role.value: registry().get(role, config.driver).sim_faults
        for role, config in ((Role.CHAMBER, station.chamber), (Role.TABLE, station.table),
                             (Role.GYRO, station.gyro))}
    known["fixture"] = FIXTURE_FAULTS
    if station.supply is not None:
        known["supply"] = registry().get(Role.SUPPLY, station.supply.driver).sim_faults
    try:
        fault_plan = FaultPlan([parse_injection(spec, known) for spec in specs])
        fault_plan.check_steps([step.step_id for step in plan.steps])
    except FaultSpecError as exc:
        raise BadInput(str(exc)) from None
    return fault_plan


def cmd_resume(args: argparse.Namespace) -> int:
    quiet_library_logs(getattr(args, "debug", False))
    folder = RunFolder.open(Path(args.run_dir))
    with contextlib.ExitStack() as held:
        # Before reading the manifest: a live controller may be writing it.
        _announce_stale(held.enter_context(run_folder_lock(folder.path)))
        return _resume_locked(args, folder, held)


def _resume_locked(args: argparse.Namespace, folder: RunFolder, held: contextlib.ExitStack) -> int:
    manifest = folder.read_manifest()
    if (folder.path / "journal.jsonl").exists():
        folder.open_journal()     # a torn last line (power cut) is set aside and journaled first
    if args.speed not in (None, "1", "1.0") and manifest.get("mode") != "sim":
        # The rule run applies: real chambers and tables live in real time.
        raise BadInput(f"--speed {args.speed}: only --sim runs can change the clock; "
                       "real instruments run at --speed 1")
    if steps_completed_run(folder.journal_events()):
        return _close_completed(args, folder)
    inputs = manifest["inputs"]
    for role, entry in inputs.items():
        source = Path(entry["source"])
        if not source.is_file():
            raise BadInput(f"{source}: the {role} file of this run is gone; restore it to resume "
                           f"(a copy is in {folder.path / entry['copy']})")
        if sha256_file(source) != entry["sha256"]:
            raise BadInput(f"{source}: the {role} file changed since the run started "
                           f"(SHA-256 differs from {folder.path / entry['copy']}); "
                           "resume needs the inputs the run started with")
    station = inputs.get("station", {}).get("source")
    # the inputs were confined (or allowed) when the run started, and their SHA-256 is checked
    procedure = load_procedure(inputs["procedure"]["source"], station_path=station,
                               allow_outside=True)
    plan = expand_plan(procedure)
    if [s.step_id for s in plan.steps] != manifest.get("steps"):
        raise BadInput(f"{folder.path}: the expanded plan differs from the one the run started with")
    if not folder.journal_events():
        # Cut before run_started fixed anything: the plan record may be missing or not yet
        # in the manifest. It is written again, as run writes it (same inputs, checked above).
        record = write_plan_record(folder.path, procedure, plan)
        folder.update_manifest(plan_sha256=sha256_file(record))
    sim = manifest.get("mode") == "sim"
    speed = args.speed if args.speed is not None else manifest.get("speed")
    clock = _clock_for(speed, sim)
    seed = manifest.get("seed")
    held.enter_context(_station_locks(procedure, sim))
    resumes = int(manifest.get("resumes", 0)) + 1
    folder.update_manifest(resumes=resumes, pid=os.getpid())
    # A dry run keeps its seed: every attempt draws from (seed, step id, attempt), and a
    # resumed session's attempts are new attempts, so nothing is replayed.
    signer = run_signer(getattr(args, "signing_key", None), procedure.station.signing_key)
    return _execute(folder, procedure, plan, clock, sim, seed, signer=signer,
                    on_sim_started=args.on_sim_started)


def _close_completed(args: argparse.Namespace, folder: RunFolder) -> int:
    """Every step is recorded: close the run, or repair a closed run's tail (run_close.py)."""
    signer = report_signer(folder.path, getattr(args, "signing_key", None))

    def build(run: RunFolder, journal) -> dict[str, Any]:

        return build_report(run.path, journal=journal, signer=signer)

    repair = close_completed(folder, signer, build)
    print(f"{folder.path}: run already complete; " + "; ".join(repair.lines()))
    results = folder.path / "report" / "results.json"
    return print_verdict(json.loads(results.read_text())) if results.is_file() else EXIT_OK


def _operator() -> str:
    try:
        return getpass.getuser()
    except Exception:  # noqa: BLE001 - no passwd entry in some containers
        return "unknown"


def run_signer(cli_key: str | None, station_key: Path | None) -> Signer | None:
    """The key that seals this run: --signing-key, else $GYROCAL_SIGNING_KEY, else the station's."""
    if cli_key is not None:
        return signer_from(cli_key)
    from_env = signer_from(None)
    if from_env is not None:
        return from_env
    return signer_from(station_key) if station_key is not None else None


def report_signer(run_dir: Path, cli_key: str | None) -> Signer | None:
    """The key that seals a rebuilt report: as for run, with the run's own station file."""
    station_key = None
    try:
        source = RunFolder.open(run_dir).read_manifest()["inputs"]["station"]["source"]
        station_key = load_station(source).signing_key
    except (KeyError, OSError, ValueError, ProcedureError):
        station_key = None  # no usable station file: only --signing-key or the env var
    return run_signer(cli_key, station_key)


def cmd_keys(args: argparse.Namespace) -> int:
    """``gyrocal keys``: the station's Ed25519 pair; the private half readable by its owner only."""
    pair = generate_key_pair(Path(args.out), args.name)
    print(f"private key: {pair.private} (mode 600: keep it on the station, never in a run "
          "folder)")
    print(f"public key:  {pair.public} (give it to QA: gyrocal verify RUN_DIR --key "
          f"{pair.public})")
    print(f"fingerprint: {pair.fingerprint}")
    print(f"use it: station file `signing_key: {pair.private}` or "
          f"GYROCAL_SIGNING_KEY={pair.private}")
    return EXIT_OK


def _execute(folder: RunFolder, procedure: Procedure, plan: Plan, clock, sim: bool,
             seed: int | None, fault_plan=None, signer: Signer | None = None,
             on_sim_started: SimStarted | None = None) -> int:
    journal = folder.open_journal()
    manifest = folder.read_manifest()
    Notifier(procedure.station.notify, _run_label(manifest, procedure)).attach(journal)
    if journal.count == 0:
        # What the auditor must be able to tie to this history: the inputs, the frozen
        # plan and who/what the run was for. The manifest stays mutable run state.
        journal.append(JournalEvent.RUN_STARTED, run_id=manifest["run_id"],
                       procedure=procedure.name, steps=len(plan.steps), sim=sim, seed=seed,
                       inputs={role: entry["sha256"]
                               for role, entry in (manifest.get("inputs") or {}).items()},
                       plan_sha256=manifest.get("plan_sha256"),
                       identity={key: manifest.get(key) for key in IDENTITY_KEYS},
                       signing_key=None if signer is None else signer.fingerprint)
    # What a crash left between a file's write and its journal line: set aside, named.
    set_aside(folder.path, journal, folder.journal_events(), manifest)
    closing = ClosingSignals()
    with closing.installed():
        try:
            code = _execute_journaled(folder, journal, procedure, plan, clock, sim, seed,
                                      fault_plan, signer, on_sim_started, closing)
        finally:
            if signer is not None and not journal.closed:
                signer.seal(journal, manifest["run_id"], reason="controller exit")
            folder.close()
    if closing.received and code != EXIT_FAULT:   # a faulted run has said how to resume
        print(f"gyrocal: stopped by signal {closing.received[0]} while the run was being closed; "
              f"its record is complete and closed ({folder.path}); exit {EXIT_FAULT} as for "
              "any interrupt", file=sys.stderr)
        return EXIT_FAULT
    return code


def print_verdict(results: dict[str, Any]) -> int:
    """The acceptance lines and the overall verdict; exit 1 unless PASS."""
    for item in results.get("acceptance", []):
        verdict = item.get("decision") or ("PASS" if item["pass"] else "FAIL")
        print(f"  {verdict}  {item['name']}: {verdict_line(item)}")
    verdict = results.get("verdict") or {}
    overall = verdict.get("overall")
    if overall == "INVALID":
        print("  INVALID: the numbers are not physically possible, no limit was judged:")
        for reason in verdict["invalid_because"]:
            print(f"    {reason}")
    for reason in verdict.get("blocked_because", []):
        print(f"  BLOCKED: {reason}")
    if overall == "INCOMPLETE":
        print(f"  INCOMPLETE: not evaluated: {', '.join(verdict.get('not_evaluated') or [])}")
    failed = any(not a.get("pass") for a in results.get("acceptance", []))
    return EXIT_ACCEPTANCE_FAILED if failed or overall not in (None, "PASS") else EXIT_OK


def verdict_line(item: dict[str, Any]) -> str:
    """``value ± U unit (max L unit, rule)``: U on every line, so a value near its limit shows it."""
    unit = f" {item['unit']}" if item.get("unit") else ""
    rule = item.get("decision_rule") or "simple"
    guard = (f", guard band {item['guard_band']:.2g}{unit}"
             if rule == "guarded" and item.get("guard_band") else "")
    limit = f"({item['kind']} {item['limit']:.6g}{unit}, {rule} rule{guard})"
    if item.get("identifiable") is False:
        bound = item.get("upper_bound_95")
        shown = f"{bound:.3g}{unit}" if isinstance(bound, (int, float)) else "unknown"
        return f"not identifiable from this record (95 % upper bound {shown}) {limit}"
    if item.get("value") is None:
        return f"{item.get('why') or 'not computed'} {limit}"
    u_text = f" ± {item['U']:.2g}" if isinstance(item.get("U"), (int, float)) else \
        " (U not stated)"
    return f"{item['value']:.6g}{u_text}{unit} {limit}"


def _run_label(manifest: dict[str, Any], procedure: Procedure) -> str:
    return f"{procedure.unit_under_test.serial} run {manifest.get('run_id')}"


def _execute_journaled(folder: RunFolder, journal, procedure: Procedure, plan: Plan, clock,
                       sim: bool, seed: int | None, fault_plan=None,
                       signer: Signer | None = None,
                       on_sim_started: SimStarted | None = None,
                       closing: ClosingSignals | None = None) -> int:

    console = RetryConsole()

    def on_retry(role: str, attempt: int, exc: InstrumentError) -> None:
        journal.append(JournalEvent.RETRY, instrument=role, attempt=attempt, command=exc.command,
                       detail=exc.detail, reply=_text(exc.reply))
        console.note(role, exc)

    results: dict[str, Any] = {}

    def on_finished() -> None:
        results.update(_build_report(folder, signer))

    simulated: Any = None
    try:
        with station_instruments(procedure, clock, sim, seed, on_retry,
                                 on_sim_started) as (instruments, simulated):
            before_step = None
            if fault_plan is not None and simulated is not None:
                fault_plan.arm_due(simulated, None, journal)

                def before_step(step: Any) -> None:
                    fault_plan.arm_due(simulated, step.step_id, journal)

            engine = RunEngine(folder, list(plan.steps), instruments, _policy(procedure),
                               progress=Progress(), on_finished=on_finished,
                               before_step=before_step,
                               operator=_fixture_operator(procedure, folder, simulated),
                               mountings={m.name: m.up for m in procedure.mountings},
                               on_attempt=None if simulated is None else simulated.begin_attempt)
            if closing is not None:
                closing.arm()      # from here until the seal, a signal waits for the close
            try:
                engine.run()
            finally:
                if closing is not None:
                    closing.received.extend(engine.deferred_signals)
        console.flush()
        journal.append(JournalEvent.RUN_CLOSED, outcome="completed")
    except RunFaultError as exc:
        console.flush()
        print(f"gyrocal: fault: {exc}", file=sys.stderr)
        _report_simulator_crash(simulated, journal)
        return EXIT_FAULT
    except LockBusyError as exc:
        console.flush()
        # The serial lock, taken after the identity queries and before preflight.
        journal.append(JournalEvent.FAULT, message=str(exc), state="connecting")
        folder.update_manifest(state="faulted", last_fault=str(exc))
        print(f"gyrocal: {exc}; nothing was commanded", file=sys.stderr)
        return EXIT_FAULT
    except InstrumentError as exc:
        console.flush()
        # Raised while connecting, before the engine owned the instruments.
        journal.append(JournalEvent.FAULT, message=str(exc), state="connecting")
        folder.update_manifest(state="faulted", last_fault=str(exc))
        print(f"gyrocal: fault: {exc}; nothing was commanded. Resume with "
              f"`gyrocal resume {folder.path}` when the instrument answers", file=sys.stderr)
        return EXIT_FAULT
    print(f"run complete: {folder.path}")
    return print_verdict(results)


def _report_simulator_crash(simulated: Any, journal) -> None:
    """A simulator that died shows up to the drivers as silence; say what really happened."""
    error = getattr(getattr(simulated, "gyro_port", None), "error", None)
    if error is not None:
        message = f"simulated gyro stopped: {type(error).__name__}: {error}"
        journal.append(JournalEvent.SIMULATOR_ERROR, message=message)
        print(f"gyrocal: {message}", file=sys.stderr)


def _build_report(folder: RunFolder, signer: Signer | None) -> dict[str, Any]:

    # The engine holds the journal open; appending through it keeps the hash chain whole.
    return build_report(folder.path, journal=folder.open_journal(), signer=signer)


def _text(reply: Any) -> Any:
    return reply.decode("latin-1") if isinstance(reply, bytes) else reply


# -- demo --------------------------------------------------------------------------------

def cmd_demo(args: argparse.Namespace) -> int:
    """The dry run a new user sees: two acts, both against simulated instruments.

    1. The smoke procedure end to end: connect, preflight, ramp, soak, dwells,
       the report and its audit check.
    2. The discrepancy workflow: the same procedure on a station whose gyro
       carries an effect its nominal model lacks; ``gyrocal discrepancy`` with
       the nominal model must name the effect and show the gap shrink.
    """

    root = Path(__file__).resolve().parents[1]
    procedure = root / "procedures" / "smoke.yaml"
    out = Path(args.out) if args.out else Path("runs") / f"demo-{new_run_id()}"
    debug = getattr(args, "debug", False)

    print(f"== 1/2  {procedure.relative_to(root)} against simulated instruments ==")
    # A demo station key, made for this demo and kept beside its runs: it shows the
    # mechanism, not authenticity (whoever has the folder has the private key too). A real
    # station keeps its key on the station (gyrocal keys), and QA keeps the public half.
    keys = _demo_keys(out / "demo-station-keys")
    print(f"demo station key {keys.fingerprint} (public half: {keys.public}; kept beside "
          "the runs, so it demonstrates signing, not authenticity)")
    code = cmd_run(argparse.Namespace(
        procedure=str(procedure), station=None, sim=True, out=str(out / "smoke"), speed="max",
        seed=1, operator="demo", sim_station=None, debug=debug,
        signing_key=str(keys.private), on_sim_started=None, allow_outside_paths=False))
    if code == EXIT_FAULT:
        return code
    print(f"report: {out / 'smoke' / 'report' / 'report.html'}")


    # Certified first, verified last (below): the certificate is part of the audited history.
    certificate, number, _ = certify_run(
        out / "smoke", customer="Demo customer",
        approval=Approval("Demo approver", "Quality manager", dt.date.today()),
        signer=signer_from(keys.private))
    print(f"certificate {number}: {certificate} (SIMULATED — not a calibration)")

    station = root / "stations" / "sim-hidden-effect.yaml"
    nominal = root / "gyro-models" / "nominal-fog.yaml"
    print(f"\n== 2/2  discrepancy: {station.relative_to(root)} carries an effect "
          f"{nominal.relative_to(root)} lacks ==")
    hidden_code = cmd_run(argparse.Namespace(
        procedure=str(procedure), station=None, sim=True, out=str(out / "hidden-effect"),
        speed="max", seed=2, operator="demo", sim_station=str(station), debug=debug,
        signing_key=str(keys.private), on_sim_started=None, allow_outside_paths=False))
    if hidden_code == EXIT_FAULT:
        return hidden_code
    document = run_discrepancy(nominal, out / "hidden-effect", out / "discrepancy")
    for found in document["found"]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in found["parameters"].items())
        print(f"named: {found['name']} ({params}), probability {found['probability']:.3f}")
    if not document["found"]:
        print("named: nothing")
    gap = document["gap"]
    print(f"gap ({gap['metric']}): before {gap['before']:.4g} → after {gap['after']:.4g} "
          f"(noise floor {gap['noise_floor']:.4g})")
    print(f"story: {out / 'discrepancy' / 'discrepancy.html'}")

    print(f"\n== audit: gyrocal verify RUN_DIR --key {keys.public} ==")
    audits = [verify_run_folder(out / each, public_key=keys.public)
              for each in ("smoke", "hidden-effect")]
    for each in audits:
        print(each.summary() if each.ok else f"{each.run_dir}: FAILED: {each.failure}")
    if not all(each.ok for each in audits):
        return EXIT_ACCEPTANCE_FAILED
    return code


def _demo_keys(folder: Path) -> KeyPairFiles:
    """The demo's key pair: made on the first demo into this folder, reused after."""
    private, public = folder / "station.key", folder / "station.pub"
    if private.exists() and public.exists():
        return KeyPairFiles(private, public, fingerprint(load_public_key(public)))
    return generate_key_pair(folder)
