"""One run session: the instruments connected, the journal opened, the engine run, the run closed.

``run`` and ``resume`` differ only in how they reach a run folder; from there a
session is the same: the ``run_started`` payload on a new journal, crash
leftovers set aside, signals deferred until the seal, a fault at any point
reported as exit 3 with the record closed and resumable.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import Any

from gyrocal.app.requests import SimStarted
from gyrocal.app.verdict import print_verdict
from gyrocal.errors import EXIT_FAULT, BadInput
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.factory import Instruments, open_instruments
from gyrocal.instruments.sim.fault_plan import FaultPlan
from gyrocal.instruments.sim.station_sim import SimulatedStation
from gyrocal.orchestrator.engine import EnginePolicy, RunEngine
from gyrocal.orchestrator.interrupts import ClosingSignals
from gyrocal.orchestrator.notify import Notifier
from gyrocal.orchestrator.plan import Plan
from gyrocal.orchestrator.procedure import Procedure
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.remount import (
    FileConfirmOperator,
    SimulatedFixtureOperator,
)
from gyrocal.orchestrator.retry_console import RetryConsole
from gyrocal.orchestrator.run_errors import RunFaultError
from gyrocal.orchestrator.station import SupplyConfig
from gyrocal.orchestrator.station_fit import check_runnable
from gyrocal.orchestrator.unit_power import UnitPowerPolicy
from gyrocal.record.journal import JournalEvent
from gyrocal.record.locks import (
    LockBusyError,
    identity_locks,
)
from gyrocal.record.run_folder import IDENTITY_KEYS, RunFolder
from gyrocal.record.signing import (
    Signer,
)
from gyrocal.record.strays import set_aside
from gyrocal.reports.build import build_report


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
                simulated = SimulatedStation(station, clock, seed=seed, sample_rate_hz=fs_hz,
                                             unit_serial=procedure.unit_under_test.serial).start()
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


def execute(folder: RunFolder, procedure: Procedure, plan: Plan, clock, sim: bool,
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
            code = execute_journaled(folder, journal, procedure, plan, clock, sim, seed,
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


def execute_journaled(folder: RunFolder, journal, procedure: Procedure, plan: Plan, clock,
                      sim: bool, seed: int | None, fault_plan=None,
                      signer: Signer | None = None,
                      on_sim_started: SimStarted | None = None,
                      closing: ClosingSignals | None = None) -> int:
    """Connect, run the engine, close the journal; a fault before or during is exit 3."""
    console = RetryConsole()

    def on_retry(role: str, attempt: int, exc: InstrumentError) -> None:
        journal.append(JournalEvent.RETRY, instrument=role, attempt=attempt, command=exc.command,
                       detail=exc.detail, reply=_text(exc.reply))
        console.note(role, exc)

    results: dict[str, Any] = {}
    simulated: Any = None
    try:
        with station_instruments(procedure, clock, sim, seed, on_retry,
                                 on_sim_started) as (instruments, simulated):
            engine = _engine(folder, journal, procedure, plan, instruments, simulated,
                             fault_plan, lambda: results.update(_build_report(folder, signer)))
            if closing is not None:
                closing.arm()      # from here until the seal, a signal waits for the close
            try:
                engine.run()
            finally:
                if closing is not None:
                    closing.received.extend(engine.deferred_signals)
        console.flush()
        journal.append(JournalEvent.RUN_CLOSED, outcome="completed")
    except (RunFaultError, LockBusyError, InstrumentError) as exc:
        console.flush()
        return _faulted(folder, journal, exc, simulated)
    print(f"run complete: {folder.path}")
    return print_verdict(results)


def _engine(folder: RunFolder, journal, procedure: Procedure, plan: Plan,
            instruments: Instruments, simulated: Any, fault_plan,
            on_finished: Callable[[], None]) -> RunEngine:
    before_step = None
    if fault_plan is not None and simulated is not None:
        _arm_faults(fault_plan, simulated, None, journal)

        def before_step(step: Any) -> None:
            _arm_faults(fault_plan, simulated, step.step_id, journal)

    return RunEngine(folder, list(plan.steps), instruments, _policy(procedure),
                     progress=Progress(), on_finished=on_finished,
                     before_step=before_step,
                     operator=_fixture_operator(procedure, folder, simulated),
                     mountings={m.name: m.up for m in procedure.mountings},
                     rehearsal=simulated)


def _arm_faults(fault_plan: FaultPlan, simulated: Any, step_id: str | None, journal) -> None:
    """Arm the dry run's injections due before ``step_id``; each one armed is journaled, so
    the audit trail says which troubles were deliberate."""
    for injection in fault_plan.arm_due(simulated, step_id):
        journal.append(JournalEvent.FAULT_INJECTED, instrument=injection.role,
                       fault=injection.fault, count=injection.count, params=injection.params,
                       before_step=step_id, spec=injection.text)


def _faulted(folder: RunFolder, journal, exc: Exception, simulated: Any) -> int:
    """What the console and the record say of a fault, by where it happened."""
    if isinstance(exc, RunFaultError):
        print(f"gyrocal: fault: {exc}", file=sys.stderr)
        _report_simulator_crash(simulated, journal)
        return EXIT_FAULT
    # Raised while connecting (the serial lock, taken after the identity queries and
    # before preflight, or an instrument), before the engine owned the instruments.
    journal.append(JournalEvent.FAULT, message=str(exc), state="connecting")
    folder.update_manifest(state="faulted", last_fault=str(exc))
    if isinstance(exc, LockBusyError):
        print(f"gyrocal: {exc}; nothing was commanded", file=sys.stderr)
    else:
        print(f"gyrocal: fault: {exc}; nothing was commanded. Resume with "
              f"`gyrocal resume {folder.path}` when the instrument answers", file=sys.stderr)
    return EXIT_FAULT


def _run_label(manifest: dict[str, Any], procedure: Procedure) -> str:
    return f"{procedure.unit_under_test.serial} run {manifest.get('run_id')}"


def _report_simulator_crash(simulated: SimulatedStation | None, journal) -> None:
    """A simulator that died shows up to the drivers as silence; say what really happened."""
    if simulated is None:
        return
    error = getattr(simulated.gyro_port, "error", None)   # a replayed capture has none
    if error is not None:
        message = f"simulated gyro stopped: {type(error).__name__}: {error}"
        journal.append(JournalEvent.SIMULATOR_ERROR, message=message)
        print(f"gyrocal: {message}", file=sys.stderr)


def _build_report(folder: RunFolder, signer: Signer | None) -> dict[str, Any]:

    # The engine holds the journal open; appending through it keeps the hash chain whole.
    return build_report(folder.path, journal=folder.open_journal(), signer=signer)


def _text(reply: Any) -> Any:
    return reply.decode("latin-1") if isinstance(reply, bytes) else reply
