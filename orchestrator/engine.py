"""The engine that runs a plan on instruments: how, with pause, resume and cleanup.

The plan (``orchestrator/plan.py``) says *what* to do, step by step; this
module says *how*: it commands the chamber and the table, waits on the one
clock, logs the gyro, journals every event, and whatever happens — a fault,
Ctrl-C, a bug — leaves the instruments in the station's safe state before it
returns. Completed steps are read back from the journal, so a resumed run
continues at the first step not completed and never repeats one.

The same code runs against hardware (``RealClock``) and against simulators
(``SimClock``): there is no dry-run branch in here.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

from gyrocal.errors import NO_ROOM_ERRNOS
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.factory import Instruments
from gyrocal.instruments.identity import serial_change
from gyrocal.instruments.interfaces import ConfigurableGyro, IdentifyingGyro, Identity
from gyrocal.models.imu_model import Mounting
from gyrocal.models.sim_state import SimStateError
from gyrocal.orchestrator.acquisition import Acquisition, AcquisitionPolicy, StepResult
from gyrocal.orchestrator.conditions import Conditions
from gyrocal.orchestrator.interrupts import GatedChamber, GatedTable, InterruptGate
from gyrocal.orchestrator.machine import RunStateMachine
from gyrocal.orchestrator.plan import PlanStep
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.remount import FixtureOperator, RemountExecutor
from gyrocal.orchestrator.run_errors import RunFaultError, StepQualityError
from gyrocal.orchestrator.safe_state import SafeOutcome, SafePolicy, make_safe
from gyrocal.orchestrator.table_synthesis import (
    REST_BEFORE_SYNTHESIS_S,
    Sinusoid,
    start_sinusoid,
)
from gyrocal.orchestrator.turn_on import power_cycle, wait_first_frame
from gyrocal.orchestrator.unit_power import UnitPowerPolicy, power_on
from gyrocal.orchestrator.unit_power import check as check_power
from gyrocal.record.journal import JournalEvent
from gyrocal.record.logged_steps import attempts_started, bad_attempts, counted_attempts
from gyrocal.record.run_folder import RunFolder, serials_begun_with
from gyrocal.record.step_kind import StepKind

#: An operator creates this file in the run folder to pause before the next step.
PAUSE_FILE = "PAUSE"
#: a tilt step's angle counts as reached within this (the position readout has 1e-6 deg)
POSITION_BAND_DEG = 0.001
#: the longest a position move may take before it is a fault (±90 deg at any sane limit)
MOVE_TIMEOUT_S = 120.0


#: Step kinds that act after their ``step_completed`` line: a drive-off static closes the
#: interlock, a frequency-response step leaves synthesis mode, a tilt step (the last of a
#: run of them) returns the table to 0 deg and rate mode, a magnetic step switches the coil
#: off. In a dry run the state the next step starts from is journaled after that act, in a
#: ``sim_state_saved`` line; every other step's is on its ``step_completed`` line.
ACTS_AFTER_COMPLETED = frozenset({StepKind.DRIVE_OFF, StepKind.FREQUENCY_RESPONSE,
                                  StepKind.MAGNETIC, StepKind.TILT})


#: events after which a run is no cut-short uninterrupted run (engine._restore_simulation)
_NOT_CUT_SHORT = frozenset({JournalEvent.FAULT, JournalEvent.SIMULATOR_ERROR})


class Rehearsal(Protocol):
    """A simulated station, as the engine sees it in a dry run (``station_sim.py``).

    Exactness of a seeded dry run rests on two things the engine tells it: which
    attempt's random streams to draw from, and where a resumed run takes up.
    The rule for a resumed run (issue 30): it equals the uninterrupted run step
    for step. Every completed step's ``step_completed`` line of a dry run carries
    the station's state at that moment (``sim_state``); a resumed run restores
    the last one right before its first remaining step, after its own preflight
    and re-soak, so that step starts from the state the uninterrupted run had
    (after a step that acts after its ``step_completed`` line, the state
    journaled after the act: ``ACTS_AFTER_COMPLETED``).
    A step cut mid-way is run again from its start; its new attempt draws from
    the streams of the attempt the uninterrupted run would have been at (one
    more than the step's ``step_bad`` attempts: an attempt cut by a kill is no
    attempt of the uninterrupted run), though the journal numbers it after the
    cut one, whose chunks stay as they are. So the attempt that counts in the
    resumed run has the samples of the attempt that counts in the uninterrupted
    one, value for value and time stamp for time stamp; only its number, the
    lines recording the interruption and the resume, wall times and the run
    identity differ.
    """

    def begin_attempt(self, step_id: str, attempt: int) -> None:
        """Draw every random stream from (seed, ``step_id``, ``attempt``) from here."""

    def snapshot(self) -> dict[str, Any] | None:
        """The simulated state now (JSON data), or None when it cannot all be kept."""

    def restore(self, state: dict[str, Any]) -> bool:
        """Put the simulated station back into a snapshot's state (False: it keeps none)."""

    def gyro_command_heard(self) -> Callable[[], bool] | None:
        """Wait until the simulated gyro has taken the command just written (None: it takes
        none); the command's time passes only then, so its answer lands at one place."""

    def gyro_bytes_waiting(self) -> Callable[[], bool] | None:
        """What a first-frame poll asks the simulated gyro: did it make bytes since the
        last poll? (None: the gyro cannot tell; the poll waits in wall time, ``turn_on.py``)"""


@dataclass(frozen=True)
class EnginePolicy:
    """Tunables with lab-sensible defaults; procedures and stations may override them."""

    poll_s: float = 10.0                # chamber/table polling period while waiting (clock time)
    chunk_s: float = 60.0               # seconds of samples per Parquet chunk
    block_s: float = 10.0               # seconds of samples per driver read (and per table readback)
    read_timeout_margin_s: float = 5.0  # wall seconds beyond the block's wall duration before a read times out
    rate_tolerance_dps: float = 0.05    # table "at rate" band (plus 0.1 % of the rate)
    spin_timeout_factor: float = 3.0    # × the acceleration time before "table never reached rate"
    max_loss_fraction: float = 0.001    # lost + corrupt frames allowed per logged step
    max_repeats: int = 2                # bad logged step (frame loss, gyro read failure) repeated at most this many times
    safe_setpoint_c: float | None = 25.0  # None = chamber standby is not supported: hold setpoint
    chamber_retries: int = 3            # attempts of each safe-state action (station chamber.retries)
    table_retries: int = 3              # (station table.retries)
    table_hold: bool = False            # safe state holds the axis under servo (horizontal table)
    pause_poll_s: float = 0.5           # wall seconds between looks at RUN_DIR/PAUSE while paused
    unit_power: UnitPowerPolicy | None = None   # the station's supply for the unit, if any


class RunEngine:
    """Executes the steps of a plan that the journal does not list as completed."""

    def __init__(
        self,
        folder: RunFolder,
        steps: list[PlanStep],
        instruments: Instruments,
        policy: EnginePolicy,
        progress: Progress | None = None,
        on_finished: Callable[[], None] | None = None,
        before_step: Callable[[PlanStep], None] | None = None,
        operator: FixtureOperator | None = None,
        mountings: Mapping[str, Mounting] | None = None,
        rehearsal: Rehearsal | None = None,
    ) -> None:
        self.folder = folder
        self.operator = operator            # who turns the IMU fixture (remount steps)
        self.mountings = dict(mountings or {})
        self.steps = steps
        # Every chamber and table call is one exchange a signal cannot cut in half (interrupts.py).
        self._gate = InterruptGate()
        instruments = replace(instruments, chamber=GatedChamber(instruments.chamber, self._gate),
                              table=GatedTable(instruments.table, self._gate))
        self.inst = instruments
        self.clock = instruments.clock
        self.policy = policy
        self.journal = folder.open_journal()
        self.machine = RunStateMachine()
        self.progress = progress or Progress(enabled=False)
        self.on_finished = on_finished
        self.before_step = before_step      # e.g. a dry run's planned fault injections
        self._step_id: str | None = None    # the plan step being executed (for fault events)
        self._attempts_before: dict[str, int] = {}  # step_id → last attempt journaled by earlier sessions
        self._bad_before: dict[str, int] = {}  # step_id → its step_bad attempts in earlier sessions
        self.rehearsal = rehearsal          # the simulated station of a dry run
        self._closing_from: int | None = None  # len(gate.deferred) when the close began
        self._t_run_start = self.clock.now_s()
        self._position_mode = False         # the table serves position mode (tilt steps)
        #: whether this session has commanded an instrument yet: a fault before the first
        #: command (identify, preflight's reads) leaves the rig as found, and says so
        self._commanded = False
        self.conditions = Conditions(instruments, self.clock, self.machine, self.journal,
                                     self.progress, policy, elapsed_s=self._elapsed,
                                     completed_fields=self._completed_fields)
        self.acquisition = Acquisition(
            instruments, self.clock, folder, self.journal, self.progress,
            AcquisitionPolicy(policy.chunk_s, policy.block_s, policy.read_timeout_margin_s),
            poll_chamber=self.conditions.poll_chamber, elapsed_s=self._elapsed,
            on_attempt=None if rehearsal is None else rehearsal.begin_attempt)
        self._executors = self._executor_registry()

    def _executor_registry(self) -> dict[StepKind, Callable[[PlanStep], None]]:
        """One executor per step kind (a registry, not a chain of string tests)."""
        executors: dict[StepKind, Callable[[PlanStep], None]] = {
            StepKind.RAMP: self.conditions.ramp,
            StepKind.SOAK: self.conditions.soak,
            StepKind.STATIC: self._log_step,
            StepKind.ALLAN: self._log_step,
            StepKind.DWELL: self._log_step,
            StepKind.DRIVE_OFF: self._drive_off_step,
            StepKind.THRESHOLD: self._log_step,
            StepKind.RATE_LIMIT: self._log_step,
            StepKind.FREQUENCY_RESPONSE: self._frequency_step,
            StepKind.MAGNETIC: self._magnetic_step,
            StepKind.TILT: self._tilt_step,
            StepKind.TURN_ON: self._turn_on_step,
            StepKind.TURN_ON_CYCLE: self._turn_on_step,
        }
        if self.operator is not None:
            executors[StepKind.REMOUNT] = self._remount_executor().execute
        return executors

    def _remount_executor(self) -> RemountExecutor:
        if self.operator is None:
            raise RunFaultError("the plan has remount steps but the run has no fixture operator")
        return RemountExecutor(
            self.inst, self.conditions, self.acquisition, self.machine, self.journal, self.folder,
            self.progress, self.operator, self.mountings, self.policy.pause_poll_s,
            attempts_before=lambda step_id: self._attempts_before.get(step_id, 0),
            elapsed_s=self._elapsed, completed_fields=self._completed_fields)

    # -- public ----------------------------------------------------------------------------
    def run(self) -> str:
        """Run to the end or to the safe state. Returns the final state ("done" or "faulted")."""
        with self._gate.installed(self.journal):
            try:
                self._connect_and_preflight()
                events = self.folder.journal_events()
                done = counted_attempts(events)
                self._attempts_before = attempts_started(events)
                self._bad_before = bad_attempts(events)
                remaining = [s for s in self.steps if s.step_id not in done]
                if done and remaining:
                    self.journal.append(JournalEvent.RESUMED, from_step=remaining[0].step_id,
                                        completed=len(done))
                    self._step_id = remaining[0].step_id
                    self._restore_conditions(remaining[0])
                    self._restore_simulation(events, remaining[0])
                self.folder.update_manifest(state="running")
                for index, step in enumerate(self.steps, start=1):
                    if step.step_id in done:
                        continue
                    self._step_id = step.step_id
                    # ETA: the plan's expected duration of this and every later step
                    eta_s = sum(s.expected_s for s in self.steps[index - 1:]
                                if s.step_id not in done)
                    self.progress.update(step_id=step.step_id, step_index=index,
                                         step_count=len(self.steps), eta_s=eta_s,
                                         step_expected_s=step.expected_s,
                                         step_started_s=self._elapsed())
                    self._pause_if_asked(step)
                    if self.before_step is not None:
                        self.before_step(step)
                    self._execute(step)
                self._step_id = None
                self._finish()
                return "done"
            except KeyboardInterrupt as exc:
                safe = self._go_safe(JournalEvent.INTERRUPTED,
                                     f"interrupted by the operator ({exc or 'Ctrl-C'})")
                raise RunFaultError(f"run interrupted; {safe.summary()}; continue with "
                                    f"`gyrocal resume {self.folder.path}`") from None
            except (InstrumentError, RunFaultError) as exc:
                safe = self._go_safe(JournalEvent.FAULT, str(exc), **_fault_fields(exc))
                raise RunFaultError(f"{exc}; {safe.summary()}; continue with "
                                    f"`gyrocal resume {self.folder.path}`") from exc
            except OSError as exc:
                if exc.errno not in NO_ROOM_ERRNOS:
                    self._go_safe(JournalEvent.FAULT, f"internal error: {exc!r}")
                    raise
                what = f"no room to write ({exc.strerror}: {exc.filename or 'a run file'})"
                safe = self._go_safe(JournalEvent.FAULT, what)
                raise RunFaultError(f"{what}; {safe.summary()}; every line already in the journal "
                                    "is kept; make room, then continue with "
                                    f"`gyrocal resume {self.folder.path}`") from None
            except BaseException as exc:
                self._go_safe(JournalEvent.FAULT, f"internal error: {exc!r}")
                raise
            finally:
                self.progress.close()

    # -- operator pause ----------------------------------------------------------------------
    @property
    def pause_file(self) -> Path:
        return self.folder.path / PAUSE_FILE

    def _pause_if_asked(self, step: PlanStep) -> None:
        """Hold between steps while ``RUN_DIR/PAUSE`` exists (``touch`` it; delete to go on).

        A pause never cuts a step in half: it takes effect before the next
        step. While paused the table is stopped and the chamber holds its
        setpoint; the wait is in wall time (an operator's pause, not
        procedure time). On going on, the next step re-commands what it needs.
        """
        if not self.pause_file.exists():
            return
        self.machine.pause()
        self.inst.table.stop()
        self.conditions.forget_demand()
        self.journal.append(JournalEvent.PAUSED, before_step=step.step_id,
                            chamber_setpoint_c=self.inst.chamber.read_setpoint_c())
        self.folder.update_manifest(state="paused")
        self.progress.update(paused=True)
        while self.pause_file.exists():
            self.conditions.poll_chamber()
            time.sleep(self.policy.pause_poll_s)
        self.inst.table.set_rate_mode()
        self.journal.append(JournalEvent.UNPAUSED, before_step=step.step_id)
        self.progress.update(paused=False, step_started_s=self._elapsed())
        self.folder.update_manifest(state="running")
        self.machine.unpause()

    # -- connection --------------------------------------------------------------------------
    def _connect_and_preflight(self) -> None:
        self.machine.connect()
        identities: dict[str, dict[str, str]] = {}
        recorded = serials_begun_with(self.folder.journal_events())   # earlier sessions'
        supply = [self.inst.supply] if self.inst.supply is not None else []
        for inst in (self.inst.chamber, self.inst.table, *supply):
            self._same_unit(identities, recorded, self._identified(inst.identify(), identities))
        if self.inst.supply is not None and self.policy.unit_power is not None:
            powered_s = self.clock.now_s()
            self._commanded = True
            power_on(self.inst.supply, self.policy.unit_power, self.journal)
            # a unit just switched on sends after its start-up delay (turn_on.py)
            wait_first_frame(self.inst.gyro, self.clock, powered_s, "preflight",
                             waiting=self._gyro_bytes_waiting())
            self._journal_start_up("preflight")
        try:
            self._confirm_gyro_configuration()
            self._ask_gyro_identity()
        finally:       # the gyro last: its identity carries what it said of its configuration
            gyro_role = self._identified(self.inst.gyro.identify(), identities)
        self._same_unit(identities, recorded, gyro_role)
        self.machine.identified()
        status = self.inst.chamber.read_status()
        if status.alarm:
            raise RunFaultError(f"chamber: preflight: alarm active ({status.detail or 'no detail'})")
        if status.profile_running:
            raise RunFaultError(f"chamber: preflight: the controller is running its own profile "
                                f"({status.run_state}); stop the profile on its front panel, "
                                "then start (or resume) the run")
        table = self.inst.table
        if not table.interlock_closed():
            self._commanded = True
            table.close_interlock()
            if not table.interlock_closed():
                raise RunFaultError("table: preflight: interlock is open and did not close")
        self._commanded = True          # from here on the rig is ours: faults make it safe
        table.set_rate_mode()
        probe = self.inst.gyro
        probe.flush()
        n_probe = max(1, int(self.inst.sample_rate_hz * 0.1))
        self.clock.elapse_reading(n_probe / self.inst.sample_rate_hz)
        block = probe.read_samples(n_probe, timeout_s=self.policy.read_timeout_margin_s)
        self.conditions.table_dps = table.read_rate_dps()
        self.conditions.chamber_c = status.temperature_c
        self.journal.append(JournalEvent.PREFLIGHT_OK, chamber_c=status.temperature_c,
                            gyro_samples=len(block), table_rate_dps=self.conditions.table_dps)
        self.machine.preflight_ok()

    def _identified(self, ident: Identity, identities: dict[str, dict[str, str]]) -> str:
        """Journal an instrument's identity and keep the manifest's copy in step (its role)."""
        identities[ident.role] = {"driver": ident.driver, "address": ident.address,
                                  "description": ident.description}
        self.journal.append(JournalEvent.INSTRUMENT_IDENTIFIED, role=ident.role, driver=ident.driver,
                            address=ident.address, description=ident.description)
        self.folder.update_manifest(instruments=identities)
        return ident.role

    def _same_unit(self, identities: dict[str, dict[str, str]], recorded: dict[str, str],
                   role: str) -> None:
        """A resumed run goes on with the units it began with: an instrument (the unit under
        test above all) reporting another serial than the one this run began with is a fault
        before its first step (exit 3): another unit's samples under this run's certificate,
        or a step measured with an instrument its traceability does not list."""
        before = recorded.get(role)
        now = serial_change(before, identities[role]["description"])
        if now is not None:
            raise RunFaultError(
                f"{role}: preflight: reports serial {now}, but this run began with serial "
                f"{before} (journal instrument_identified): another unit; reconnect serial "
                f"{before} and resume again, or start a new run for serial {now}")

    def _ask_gyro_identity(self) -> None:
        """Ask the gyro who it is (a STIM300's ``N<CR>``, ``I<CR>``, TS1524 §8.1–8.2): its
        serial goes into its identity, which the report checks against the procedure's unit
        under test; no answer is journaled as not confirmed."""
        gyro = self.inst.gyro
        if isinstance(gyro, IdentifyingGyro):
            answer = gyro.ask_identity(timeout_s=self.policy.read_timeout_margin_s,
                                       let_pass=self._let_command_pass())
            self.journal.append(JournalEvent.GYRO_IDENTITY, **answer.record())

    def _journal_start_up(self, when: str) -> None:
        """Journal what the gyro sent when it started (its start-up datagrams), if anything."""
        gyro = self.inst.gyro
        record = gyro.take_start_up() if isinstance(gyro, IdentifyingGyro) else None
        if record is not None:
            self.journal.append(JournalEvent.GYRO_START_UP, when=when, **record.record())

    def _confirm_gyro_configuration(self) -> None:
        """Ask the gyro for its configuration (a STIM300's ``C<CR>``, TS1524 §8.3) before
        anything moves: a contradiction with the station is the driver's fault (exit 3); no
        answer is journaled as not confirmed (the stream's own type is still checked)."""
        gyro = self.inst.gyro
        if not isinstance(gyro, ConfigurableGyro):
            return
        try:
            gyro.confirm_configuration(timeout_s=self.policy.read_timeout_margin_s,
                                       let_pass=self._let_command_pass())
        finally:        # what it said is journaled when it contradicts the station too
            if gyro.configuration is not None:
                self.journal.append(JournalEvent.GYRO_CONFIGURATION, **gyro.configuration.record())

    # -- step execution ----------------------------------------------------------------------
    def _execute(self, step: PlanStep) -> None:
        """Run ``step`` with the executor registered for its kind."""
        executor = self._executors.get(step.kind)
        if executor is None:
            raise RunFaultError(f"plan step {step.step_id}: no executor for kind {step.kind!r}")
        executor(step)
        if self.rehearsal is not None and step.kind in ACTS_AFTER_COMPLETED:
            state = self.rehearsal.snapshot()
            if state is not None:
                self.journal.append(JournalEvent.SIM_STATE_SAVED, step_id=step.step_id,
                                    sim_state=state)

    def _restore_conditions(self, step: PlanStep) -> None:
        """On resume, bring chamber and table back to the conditions of ``step`` first.

        The safe state left the chamber at the safe setpoint (and a restarted
        controller may hold anything), so nothing but a ramp step may assume
        the setpoint is already commanded: a soak is preceded by a ramp (the
        crash happened mid-soak), a logged step by a ramp and a full soak.
        """
        setpoint = step.setpoint_c
        if step.kind != StepKind.REMOUNT and step.mounting:
            # A restarted dry run has a new simulated fixture, and a real one may have
            # been touched while the run was down: the mounting is checked again.
            self._remount_executor().ensure(step)
        if setpoint is None or step.kind == StepKind.RAMP or self._ramp_follows(step):
            return
        self.journal.append(JournalEvent.RESTORE_CONDITIONS, step_id=step.step_id, setpoint_c=setpoint)
        self.conditions.ramp(step, journal_done=False)
        if step.kind != StepKind.SOAK:
            self.conditions.soak(step, journal_done=False)

    def _restore_simulation(self, events: list[dict[str, Any]], step: PlanStep) -> None:
        """A dry run goes on from the simulated state its last completed step journaled.

        Only when that step is the one right before ``step`` in the plan (steps
        complete in plan order) and no fault came after it: a run that faulted (a
        rehearsed fault, a stuck chamber) is not a cut-short uninterrupted run, and
        its journaled state may hold the fault itself; then, or without a state, the
        run goes on from its own re-soak, as on a real station. A step that acts
        after its ``step_completed`` line (``ACTS_AFTER_COMPLETED``) journaled the
        state after its act (``sim_state_saved``); killed before that line, the
        state on its ``step_completed`` line is restored and the act done again.
        """
        if self.rehearsal is None:
            return
        source, redo = self._state_to_restore(events, self.steps.index(step))
        if source is None:
            return
        try:
            if not self.rehearsal.restore(source["sim_state"]):
                return
        except SimStateError as exc:
            raise RunFaultError(
                f"the simulated state journaled at line {source.get('seq')} "
                f"({source.get('step_id')}) does not fit this station: {exc}; was the "
                f"journal edited? `gyrocal verify {self.folder.path}` checks it") from None
        self.journal.append(JournalEvent.SIM_STATE_RESTORED, step_id=step.step_id,
                            from_seq=source.get("seq"), clock_s=source["sim_state"].get("clock_s"))
        if redo is not None:
            self._act_after_completed(redo)

    def _state_to_restore(self, events: list[dict[str, Any]], index: int
                          ) -> tuple[dict[str, Any] | None, PlanStep | None]:
        """The journal line whose ``sim_state`` the step at ``index`` starts from, and the
        step whose act after its step_completed line must be done again (None: none)."""
        completed = [e for e in events if e.get("event") == JournalEvent.STEP_COMPLETED]
        if index == 0 or not completed \
                or completed[-1].get("step_id") != self.steps[index - 1].step_id:
            return None, None
        after = events[events.index(completed[-1]) + 1:]
        if any(e.get("event") in _NOT_CUT_SHORT for e in after):
            return None, None
        previous = self.steps[index - 1]
        if previous.kind in ACTS_AFTER_COMPLETED:
            saved = [e for e in after if e.get("event") == JournalEvent.SIM_STATE_SAVED
                     and e.get("step_id") == previous.step_id and "sim_state" in e]
            if saved:
                return saved[-1], None
            return (completed[-1], previous) if "sim_state" in completed[-1] else (None, None)
        return (completed[-1], None) if "sim_state" in completed[-1] else (None, None)

    def _act_after_completed(self, step: PlanStep) -> None:
        """What a step of ``ACTS_AFTER_COMPLETED`` does after its step_completed line."""
        acts: dict[StepKind, Callable[[PlanStep], None]] = {
            StepKind.DRIVE_OFF: self._drive_back_on,
            StepKind.FREQUENCY_RESPONSE: self._leave_synthesis,
            StepKind.MAGNETIC: self._coil_off,
            StepKind.TILT: self._leave_tilt,
        }
        acts[step.kind](step)

    def _completed_fields(self, step: PlanStep) -> dict[str, Any]:
        """What a ``step_completed`` line adds in a dry run: the simulated state at that
        moment (see :class:`Rehearsal`); the state the next step starts from, but after a
        step of ``ACTS_AFTER_COMPLETED``, which journals that after its act."""
        if self.rehearsal is None:
            return {}
        state = self.rehearsal.snapshot()
        return {} if state is None else {"sim_state": state}

    def _let_command_pass(self) -> Callable[[float], None]:
        """How a gyro command's time passes: in a dry run, once the simulated unit has the
        command (``Rehearsal.gyro_command_heard``), then the clock; else the clock alone."""
        heard = None if self.rehearsal is None else self.rehearsal.gyro_command_heard()
        if heard is None:
            return self.clock.elapse_reading

        def let_pass(span_s: float) -> None:
            heard()
            self.clock.elapse_reading(span_s)
        return let_pass

    def _gyro_bytes_waiting(self) -> Callable[[], bool] | None:
        return None if self.rehearsal is None else self.rehearsal.gyro_bytes_waiting()

    def _ramp_follows(self, step: PlanStep) -> bool:
        """A remount right before a ramp needs no temperature of its own."""
        if step.kind != StepKind.REMOUNT:
            return False
        later = self.steps[self.steps.index(step) + 1:]
        return bool(later) and later[0].kind == StepKind.RAMP

    # -- remount (multi-axis IMU) --------------------------------------------------------------
    def _elapsed(self) -> float:
        return self.clock.now_s() - self._t_run_start

    def _drive_off_step(self, step: PlanStep) -> None:
        """A static with the table's drive off: open the interlock, read it back open, log,
        then close it and re-enter rate mode at rest (read back closed).

        The table is at rest (the powered half came first); opening the interlock
        unpowers the drive, which is what the comparison needs and is itself safe. A
        fault while it is open leaves it open (safe); resume closes it at preflight.
        """
        table = self.inst.table
        self.conditions.set_table_rate(0.0)
        table.open_interlock()
        if table.interlock_closed():
            raise RunFaultError(f"table: {step.step_id}: the interlock did not open (read back "
                                "closed); the drive-off static cannot be logged")
        self.journal.append(JournalEvent.TABLE_DRIVE, step_id=step.step_id, drive="off",
                            interlock_closed=False)
        self._log_step(step)
        self._drive_back_on(step)

    def _drive_back_on(self, step: PlanStep) -> None:
        """After a drive-off static: close the interlock (read back) and re-enter rate mode."""
        table = self.inst.table
        table.close_interlock()
        if not table.interlock_closed():
            raise RunFaultError(f"table: after {step.step_id}: the interlock did not close again")
        table.set_rate_mode()
        table.set_rate_dps(0.0)
        self.journal.append(JournalEvent.TABLE_DRIVE, step_id=step.step_id, drive="on",
                            interlock_closed=True)

    def _frequency_step(self, step: PlanStep) -> None:
        """A frequency-response step: from rest, the table turns the step's sinusoid
        (synthesis mode, journaled with its start), ``settle_s`` of whole periods pass, the
        gyro is logged against the sinusoid, then the table is back in rate mode at rest.

        A fault mid-sinusoid leaves it to the safe state (the driver's stop ends synthesis,
        TM-8004 §4.7.6); a resumed run starts the step again from rest.
        """
        table = self.inst.table
        if step.freq_hz is None or step.amplitude_dps is None:
            raise RunFaultError(f"plan step {step.step_id}: no sinusoid in the plan")
        self.conditions.set_table_rate(0.0, step.accel_dps2)
        self.clock.sleep(REST_BEFORE_SYNTHESIS_S)
        self.machine.spin()
        sine = start_sinusoid(table, self.clock.now_s, step.amplitude_dps, step.freq_hz)
        self.conditions.forget_demand()
        self.journal.append(JournalEvent.TABLE_SYNTHESIS, step_id=step.step_id,
                            amplitude_dps=sine.amplitude_dps, freq_hz=sine.freq_hz,
                            displacement_deg=round(sine.displacement_deg, 9),
                            start_s=round(sine.start_s - self._t_run_start, 6))
        if step.settle_s > REST_BEFORE_SYNTHESIS_S:
            self.machine.settle()
            self.clock.sleep(step.settle_s - REST_BEFORE_SYNTHESIS_S)
        self.machine.settled()
        self._log_step(step, reference=sine)
        self._leave_synthesis(step)

    def _leave_synthesis(self, step: PlanStep) -> None:
        """After a frequency-response step: the table back in rate mode, at rest."""
        table = self.inst.table
        table.set_rate_mode()
        table.set_rate_dps(0.0)
        self.conditions.forget_demand()
        self.conditions.set_table_rate(0.0, step.accel_dps2)

    def _tilt_step(self, step: PlanStep) -> None:
        """The table (axis horizontal) as the indexing head: position mode, move to the step's
        angle, wait until the position reads it back, settle, log. After the last tilt step
        of a run of them the table goes back to 0 and to rate mode at rest."""
        table = self.inst.table
        if not table.serves_position or step.angle_deg is None:
            raise RunFaultError(f"table: {step.step_id}: the table driver has no position mode")
        if not self._position_mode:
            self.conditions.set_table_rate(0.0)
            table.set_position_mode()
            self._position_mode = True
        read_deg = self._move_to_angle(step, step.angle_deg)
        self.journal.append(JournalEvent.TABLE_POSITION, step_id=step.step_id,
                            angle_deg=step.angle_deg, read_deg=read_deg)
        self.clock.sleep(step.settle_s)
        self._log_step(step)
        self._leave_tilt(step)

    def _leave_tilt(self, step: PlanStep) -> None:
        """After the last tilt step of a run of them: the table to 0 deg, rate mode, at rest."""
        following = self.steps[self.steps.index(step) + 1:]
        if not following or following[0].kind != StepKind.TILT:
            table = self.inst.table
            self._move_to_angle(step, 0.0)
            table.set_rate_mode()
            table.set_rate_dps(0.0)
            self._position_mode = False

    def _move_to_angle(self, step: PlanStep, angle_deg: float) -> float:
        """Demand ``angle_deg``, poll the position until it reads it (within POSITION_BAND_DEG)."""
        table = self.inst.table
        table.set_position_deg(angle_deg)
        deadline = self.clock.now_s() + MOVE_TIMEOUT_S
        while True:
            read = table.read_position_deg()
            if abs((read - angle_deg + 180.0) % 360.0 - 180.0) <= POSITION_BAND_DEG:
                return read
            if self.clock.now_s() > deadline:
                raise RunFaultError(f"table: {step.step_id}: position reads {read:.4f} deg, "
                                    f"demanded {angle_deg:g} deg, after {MOVE_TIMEOUT_S:g} s")
            self.clock.sleep(self.policy.poll_s)

    def _magnetic_step(self, step: PlanStep) -> None:
        """A static with the station's coil at the step's field: set, read back, log, read back,
        switch off (read back off). The table is at rest; a fault leaves the coil off (safe state)."""
        coil = self.inst.coil
        if coil is None or step.field_t is None:
            raise RunFaultError(f"{step.step_id}: a magnetic step needs the station's coil")
        self.conditions.set_table_rate(0.0)
        self._coil_reading(step, "set")
        self._log_step(step)
        self._coil_off(step)

    def _coil_reading(self, step: PlanStep, when: str) -> None:
        """Set the step's field (``set``) or read it back (``after``), journaled and judged."""
        coil = self.inst.coil
        assert coil is not None and step.field_t is not None
        reading = coil.set_field(step.field_t) if when == "set" else coil.read()
        problem = coil.mismatch(reading, step.field_t)
        self.journal.append(JournalEvent.COIL_FIELD, step_id=step.step_id, when=when,
                            set_field_t=step.field_t, field_t=reading.field_t,
                            positive_current_a=reading.positive_current_a,
                            negative_current_a=reading.negative_current_a,
                            ok=problem is None)
        if problem is not None:
            raise RunFaultError(f"coil: {step.step_id}: {problem}")

    def _coil_off(self, step: PlanStep) -> None:
        """After a magnetic step: the field read back, then the coil off (read back off)."""
        coil = self.inst.coil
        assert coil is not None
        self._coil_reading(step, "after")
        reading = coil.off()
        if reading.positive_on or reading.negative_on:
            raise RunFaultError(f"coil: after {step.step_id}: a channel still reads on")
        self.journal.append(JournalEvent.COIL_FIELD, step_id=step.step_id, when="off",
                            set_field_t=0.0, field_t=reading.field_t,
                            positive_current_a=reading.positive_current_a,
                            negative_current_a=reading.negative_current_a, ok=True)

    def _turn_on_step(self, step: PlanStep) -> None:
        """The table at rest, the supply switches the unit off for the step's off time
        (``settle_s``) and on; the first frame's arrival is journaled, then the step is logged
        from it (orchestrator/turn_on.py). A fault leaves the power to the station's safe
        state; a resumed run cycles the power again."""
        supply = self.inst.supply
        if supply is None:
            raise RunFaultError(f"{step.step_id}: a turn_on step needs the station's supply")
        self.conditions.set_table_rate(0.0)
        off_s = step.settle_s if step.off_s is None else step.off_s
        cycle = power_cycle(supply, self.inst.gyro, self.clock, step.step_id, off_s,
                            waiting=self._gyro_bytes_waiting())
        self._journal_start_up(step.step_id)
        self.journal.append(JournalEvent.UNIT_POWER_CYCLE, step_id=step.step_id,
                            off_clock_s=round(cycle.off_clock_s, 6),
                            on_clock_s=round(cycle.on_clock_s, 6),
                            first_frame_clock_s=round(cycle.first_frame_clock_s, 6),
                            poll_s=cycle.poll_s,
                            first_frame_after_s=round(cycle.first_frame_after_s, 6))
        # a repeatability cycle settles (unread) after the first frame, then logs
        self.clock.sleep(step.settle_s - off_s)
        self._log_step(replace(step, settle_s=0.0))

    def _log_step(self, step: PlanStep, reference: Sinusoid | None = None) -> None:
        """Log a step; a bad attempt (frame loss, a gyro read that failed) is repeated.

        A gyro read that times out or loses its port leaves a hole in the
        step's data, so it is not retried in place like a chamber or table
        command: the whole step is repeated as a new attempt, and the failure
        is journaled as a ``retry`` of the gyro. Past ``max_repeats`` the last
        gyro error (or the loss) ends the run in the safe state.
        """
        rate_dps = step.rate_dps
        settle_s = step.settle_s
        # ``reference``: the table turns this sinusoid (synthesis mode), logged as the rate        # Attempt numbers continue after those of an interrupted session: its chunks are
        # journaled with their hashes and must never be overwritten by a new attempt.
        first = self._attempts_before.get(step.step_id, 0) + 1
        attempts = first + self.policy.max_repeats
        for attempt in range(first, attempts + 1):
            # the attempt the uninterrupted run would be at (Rehearsal): its random streams
            draws = self._bad_before.get(step.step_id, 0) + attempt - first + 1
            self.journal.append(JournalEvent.STEP_STARTED, step_id=step.step_id, kind=step.kind,
                                rate_dps=rate_dps, attempt=attempt)
            if reference is None:
                self.conditions.set_table_rate(rate_dps, step.accel_dps2, settle_s,
                                               exact=step.kind == StepKind.THRESHOLD)
            self.machine.log()
            try:
                result = self.acquisition.record(step, attempt, rate_dps,
                                                 self.conditions.at_rate_since_wall_s(),
                                                 reference=reference, draw_attempt=draws)
            except InstrumentError as exc:
                if not (exc.transient and exc.instrument == self._gyro_name()) or attempt == attempts:
                    raise
                self.machine.logged()
                self.journal.append(JournalEvent.RETRY, instrument="gyro", attempt=attempt,
                                    command=exc.command, detail=exc.detail, reply=_text(exc.reply))
                self.journal.append(JournalEvent.STEP_BAD, step_id=step.step_id, attempt=attempt,
                                    reason=f"gyro read failed: {exc}")
                continue
            self.machine.logged()
            if self.inst.supply is not None and self.policy.unit_power is not None:
                check_power(self.inst.supply, self.policy.unit_power, self.journal,
                            when="step_logged", step_id=step.step_id)
            loss = result.bad_fraction
            rate_ok = result.table_rate_max_dev_dps <= self.conditions.rate_band(rate_dps)
            if result.implausible is None and loss <= self.policy.max_loss_fraction and rate_ok:
                self.journal.append(
                    JournalEvent.STEP_COMPLETED, step_id=step.step_id, attempt=attempt,
                    samples=result.samples, lost_frames=result.lost_frames,
                    crc_errors=result.crc_errors, flagged_samples=result.flagged_samples,
                    chunks=result.chunks, table_rate_max_dev_dps=result.table_rate_max_dev_dps,
                    **self._completed_fields(step))
                return
            reason = _bad_reason(result, loss, self.policy.max_loss_fraction, rate_dps,
                                 self.conditions.rate_band(rate_dps))
            self.journal.append(
                JournalEvent.STEP_BAD, step_id=step.step_id, attempt=attempt, loss_fraction=loss,
                lost_frames=result.lost_frames, crc_errors=result.crc_errors,
                flagged_samples=result.flagged_samples, limit=self.policy.max_loss_fraction,
                table_rate_max_dev_dps=result.table_rate_max_dev_dps, reason=reason)
        raise StepQualityError(
            f"step {step.step_id}: no good attempt in {self.policy.max_repeats + 1}: {reason}")

    def _gyro_name(self) -> str | None:
        return self.inst.gyro.name

    # -- the end -----------------------------------------------------------------------------
    def _finish(self) -> None:
        """After the last step: the station's safe state (read back), the report, the close.

        The report is interruptible (Ctrl-C there is an interrupted run: exit 3,
        and ``resume`` builds it again); once it is recorded nothing is left to
        stop, so from ``run_completed`` on a signal is acknowledged and the run
        closes first (``deferred_signals`` tells the caller it came).
        """
        self.conditions.set_table_rate(0.0)
        self._return_safe()
        self.machine.analyse()
        self.journal.append(JournalEvent.STEPS_DONE, steps=len(self.steps))
        self.machine.report()
        if self.on_finished is not None:
            self.on_finished()
        self._closing_from = len(self._gate.deferred)
        self._gate.shield_for_good()
        self.machine.finish()
        ended_at = _now_text()
        self.journal.append(JournalEvent.RUN_COMPLETED, ended_at=ended_at)
        self.folder.update_manifest(state="done", ended_at=ended_at)

    @property
    def deferred_signals(self) -> list[int]:
        """Signals acknowledged while the run was being closed (the caller exits 3 for them);
        not those a fault's safing deferred (that run already ends in exit 3)."""
        if self._closing_from is None:
            return []
        return list(self._gate.deferred[self._closing_from:])

    def _return_safe(self) -> None:
        """A completed run leaves the rig as ``plan`` promises: table stopped, chamber at the
        station's safe setpoint, each confirmed by read-back and journaled (``returned_safe``)."""
        policy = SafePolicy(self.policy.safe_setpoint_c, self.policy.chamber_retries,
                            self.policy.table_retries, table_hold=self.policy.table_hold)
        outcome = make_safe(self.inst.table, self.inst.chamber, policy, self.clock,
                            coil=self.inst.coil)
        for action in outcome.actions:
            print(f"gyrocal: returned to the safe state: {action.text}", file=sys.stderr)
        self.journal.append(JournalEvent.RETURNED_SAFE, **outcome.journal_fields())
        if not outcome.confirmed:
            raise RunFaultError(f"after the last step: {outcome.summary()}")

    def _go_safe(self, kind: str, message: str, **fields: Any) -> SafeOutcome:
        """Safe state, verified (``safe_state.py``): table stopped, chamber at its safe setpoint.

        The instruments are made safe *before* anything is written, so a full
        disk never stands between a fault and a stopped table, and with the
        gate shielded a second Ctrl-C cannot cut the safing short. The fault
        event records the state the run was in when the fault struck (not
        ``safing``) and its step; ``safe_state`` records what the read-backs
        confirmed, and the manifest whether everything was.
        """
        state_at_fault = self.machine.state
        if self.machine.can("fault"):
            self.machine.fault()
        self.progress.close()
        power = self.policy.unit_power
        policy = SafePolicy(self.policy.safe_setpoint_c, self.policy.chamber_retries,
                            self.policy.table_retries, power.safe_action if power else None,
                            power.attempts if power else 3, table_hold=self.policy.table_hold)
        with self._gate.shielded():
            if self._commanded:
                outcome = make_safe(self.inst.table, self.inst.chamber, policy, self.clock,
                                    self.inst.supply, self.inst.coil)
            else:   # nothing to undo: commanding a rig we never drove would be the first move
                outcome = SafeOutcome.nothing_commanded()
            outcome.print()
            if self.machine.state == "safing":
                self.machine.safed()
            try:
                self.journal.append(kind, message=message, state=state_at_fault,
                                    step_id=self._step_id, **fields)
                self.journal.append(JournalEvent.SAFE_STATE, **outcome.journal_fields())
                self.folder.update_manifest(state="faulted", ended_at=_now_text(),
                                            last_fault=message,
                                            safe_confirmed=outcome.confirmed if outcome.commanded
                                            else None)
            except OSError as exc:
                # A full disk may refuse these lines too: the rig is safe already, and the
                # console (above) is the record of it; the fault itself is still reported.
                print(f"gyrocal: could not record the fault and the safe state in the run "
                      f"folder ({exc.strerror}); the console lines above are the record",
                      file=sys.stderr)
        return outcome


def _bad_reason(result: StepResult, loss: float, limit: float, rate_dps: float,
                band_dps: float) -> str:
    """Why an attempt is not calibration data (for step_bad and the final fault)."""
    if result.implausible is not None:
        return f"gyro stream implausible: {result.implausible}"
    if loss > limit:
        flagged = (f" ({result.flagged_samples} flagged saturated/error by the gyro)"
                   if result.flagged_samples else "")
        return f"lost {loss:.3%} of frames{flagged} (limit {limit:.3%})"
    return (f"table rate strayed {result.table_rate_max_dev_dps:.4g} deg/s from "
            f"{rate_dps:g} deg/s (band {band_dps:.4g})")


def _fault_fields(exc: BaseException) -> dict[str, Any]:
    if isinstance(exc, InstrumentError):
        return {"instrument": exc.instrument, "command": exc.command, "reply": _text(exc.reply)}
    return {}


def _text(reply: Any) -> Any:
    return reply.decode("latin-1") if isinstance(reply, bytes) else reply


def _now_text() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")

