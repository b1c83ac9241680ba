"""``gyrocal validate | plan | run | resume | confirm``: wiring, not logic.

Each command loads and validates its inputs (exit 2 on a problem), creates or
reopens the run folder and hands it to a session (``session.py``). ``run`` and
``resume`` take typed requests (``requests.py``), which the command line and the
demo both build. A resumed run re-reads the procedure and station from where
they were and refuses if they changed since the run started (their SHA-256 is
in the manifest), and applies every rule ``run`` applies.
"""

from __future__ import annotations

import argparse
import contextlib
import getpass
import json
import os
import sys
from pathlib import Path
from typing import Any

from gyrocal.app.keys import report_signer, run_signer
from gyrocal.app.library_logs import quiet_library_logs
from gyrocal.app.requests import ResumeRequest, RunRequest
from gyrocal.app.session import execute
from gyrocal.app.verdict import print_verdict
from gyrocal.errors import EXIT_OK, BadInput
from gyrocal.instruments.driver_spec import Role
from gyrocal.instruments.registry import registry
from gyrocal.instruments.sim.fault_plan import FaultPlan, FaultSpecError, parse_injection
from gyrocal.instruments.sim.imu_source import FIXTURE_FAULTS
from gyrocal.models.clock import RealClock, SimClock, make_clock
from gyrocal.orchestrator.doc_links import with_doc_links
from gyrocal.orchestrator.plan import Plan, expand_plan, format_plan
from gyrocal.orchestrator.procedure import Procedure, load_procedure
from gyrocal.orchestrator.remount import (
    write_confirmation,
)
from gyrocal.orchestrator.run_close import close_completed, steps_completed_run
from gyrocal.orchestrator.station import Station
from gyrocal.orchestrator.station_fit import check_runnable, is_simulated
from gyrocal.problems import ProcedureError
from gyrocal.record.journal import sha256_file
from gyrocal.record.locks import (
    FileLock,
    instrument_locks,
    run_folder_lock,
)
from gyrocal.record.plan_record import write_plan_record
from gyrocal.record.run_folder import RunFolder, new_run_id
from gyrocal.reports.build import build_report
from gyrocal.units import format_hms


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
    return run(RunRequest.from_args(args))


def run(request: RunRequest) -> int:
    """``gyrocal run``: validate, lock the station, create the run folder, run a session."""
    quiet_library_logs(request.debug)
    procedure = load_procedure(request.procedure, station_path=request.station_path,
                               allow_outside=request.allow_outside_paths)
    plan = expand_plan(procedure)
    check_runnable(procedure, request.sim)
    check_speed(request.speed, simulated=request.sim)
    clock = _clock_for(request.speed, request.sim)
    fault_plan = _fault_plan(list(request.inject), request.sim, plan, procedure.station)
    run_dir = request.out or Path("runs") / new_run_id()
    files = _input_files(procedure)
    with contextlib.ExitStack() as held:
        # The station's instruments first: a refused second run leaves no folder behind.
        held.enter_context(station_locks(procedure, request.sim))
        folder = _create_folder(run_dir, procedure, plan, files, request)
        announce_stale(held.enter_context(run_folder_lock(folder.path)))
        record = write_plan_record(folder.path, procedure, plan)
        folder.update_manifest(plan_sha256=sha256_file(record))
        print(f"run folder: {folder.path}", file=sys.stderr)
        signer = run_signer(request.signing_key, procedure.station.signing_key)
        return execute(folder, procedure, plan, clock, request.sim, request.seed, fault_plan,
                       signer, on_sim_started=request.on_sim_started)


def check_speed(speed: str | None, *, simulated: bool) -> None:
    """The rule ``run`` and ``resume`` share: real chambers and tables live in real time;
    a faster clock would cut soaks and holds short."""
    if not simulated and speed not in (None, "1", "1.0"):
        raise BadInput(f"--speed {speed}: only --sim runs can change the clock; "
                       "real instruments run at --speed 1")


def station_locks(procedure: Procedure, sim: bool) -> contextlib.AbstractContextManager:
    """Exclusive locks on the station's instrument addresses (``--sim`` instruments are private)."""
    if sim:
        return contextlib.nullcontext([])
    station = procedure.station
    return instrument_locks({key.split(".")[0]: address
                             for key, address in station.addresses().items()})


def announce_stale(lock: FileLock) -> None:
    if lock.stale is not None:
        print(f"gyrocal: note: {lock.what}: the previous controller ({lock.stale.describe()}) "
              "ended without releasing its lock (a crash); taking over", file=sys.stderr)


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


def _create_folder(run_dir: Path, procedure: Procedure, plan: Plan, files: dict[str, Path],
                   request: RunRequest) -> RunFolder:
    return RunFolder.create(
        run_dir,
        procedure_path=files.pop("procedure"),
        station_path=files.pop("station", None),
        extra_files=files,
        manifest_fields={
            "mode": "sim" if request.sim else "station",
            "speed": request.speed_text,
            "seed": request.seed,
            "operator": request.operator or _operator(),
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
    return resume(ResumeRequest.from_args(args))


def resume(request: ResumeRequest) -> int:
    """``gyrocal resume``: the run's own inputs, checked unchanged, continue where it stopped."""
    quiet_library_logs(request.debug)
    folder = RunFolder.open(request.run_dir)
    with contextlib.ExitStack() as held:
        # Before reading the manifest: a live controller may be writing it.
        announce_stale(held.enter_context(run_folder_lock(folder.path)))
        return _resume_locked(request, folder, held)


def _resume_locked(request: ResumeRequest, folder: RunFolder, held: contextlib.ExitStack) -> int:
    manifest = folder.read_manifest()
    if (folder.path / "journal.jsonl").exists():
        folder.open_journal()     # a torn last line (power cut) is set aside and journaled first
    check_speed(request.speed, simulated=manifest.get("mode") == "sim")
    if steps_completed_run(folder.journal_events()):
        return _close_completed(request, folder)
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
    speed = request.speed if request.speed is not None else manifest.get("speed")
    clock = _clock_for(speed, sim)
    seed = manifest.get("seed")
    held.enter_context(station_locks(procedure, sim))
    resumes = int(manifest.get("resumes", 0)) + 1
    folder.update_manifest(resumes=resumes, pid=os.getpid())
    # A dry run keeps its seed: every attempt draws from (seed, step id, attempt), and a
    # resumed session's attempts are new attempts, so nothing is replayed.
    signer = run_signer(request.signing_key, procedure.station.signing_key)
    return execute(folder, procedure, plan, clock, sim, seed, signer=signer,
                    on_sim_started=request.on_sim_started)


def _close_completed(request: ResumeRequest, folder: RunFolder) -> int:
    """Every step is recorded: close the run, or repair a closed run's tail (run_close.py)."""
    signer = report_signer(folder.path, request.signing_key)

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
