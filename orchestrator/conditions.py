"""Chamber and table moves: the ramp and soak executors and the table's rate changes.

The engine decides what comes next; this class moves the chamber to a
setpoint at the procedure's rate, waits for the soak criterion, changes the
table's rate and waits until the readback shows it, checking alarms and the
interlock on the way. The ramp and soak steps are its executors.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.factory import Instruments
from gyrocal.models.clock import RealClock, SimClock
from gyrocal.orchestrator.machine import RunStateMachine
from gyrocal.orchestrator.plan import PlanStep
from gyrocal.orchestrator.progress import Progress
from gyrocal.orchestrator.run_errors import RunFaultError, SoakTimeoutError
from gyrocal.record.journal import Journal, JournalEvent
from gyrocal.record.step_kind import StepKind


class Conditions:
    """What the chamber and the table are doing, and how they are moved."""

    def __init__(self, instruments: Instruments, clock: RealClock | SimClock,
                 machine: RunStateMachine, journal: Journal, progress: Progress,
                 policy, elapsed_s: Callable[[], float],
                 completed_fields: Callable[[PlanStep], dict] | None = None) -> None:
        self.inst = instruments
        self.clock = clock
        self.machine = machine
        self.journal = journal
        self.progress = progress
        self.policy = policy          # EnginePolicy (poll_s, rate_tolerance_dps, spin_timeout_factor)
        self.elapsed_s = elapsed_s
        #: what a step_completed line adds (a dry run's simulated state: engine.Rehearsal)
        self.completed_fields = completed_fields or (lambda step: {})
        self.chamber_c: float | None = None    # last chamber reading
        self.table_dps: float | None = None    # last table rate readback
        # (rate, wall time) of the readback that confirmed the table at its present rate: a
        # logged step's frames must have been sampled after it (instruments/gyro/plausibility.py)
        self._at_rate: tuple[float, float] | None = None
        #: the last rate this run demanded of the table (None: none yet, or stopped since)
        self._demand_dps: float | None = None

    def ramp(self, step: PlanStep, journal_done: bool = True) -> None:
        """Move the chamber to the step's setpoint at the procedure's ramp rate.

        The ramp is done in software — the setpoint walks from the present
        air temperature to the target at ``ramp_c_per_min``, re-commanded every
        ``poll_s`` — so the procedure's rate holds on any controller, whatever
        its own ramp settings, and the gyro sees the dT/dt the procedure asked
        for (thermal-lag and dT/dt effects depend on it). Alarms are checked at
        every step. Without a ramp rate the setpoint is commanded at once.
        """
        ramp_c_per_min = step.ramp_c_per_min
        self.journal.append(JournalEvent.STEP_STARTED, step_id=step.step_id, kind=StepKind.RAMP,
                            setpoint_c=step.setpoint_c, ramp_c_per_min=ramp_c_per_min, attempt=1)
        self.set_table_rate(0.0)
        self.machine.ramp()
        target_c = float(step.setpoint_c)
        t_start = self.clock.now_s()
        if ramp_c_per_min:
            start_c = self.poll_chamber()
            rate_c_per_s = float(ramp_c_per_min) / 60.0
            duration_s = abs(target_c - start_c) / rate_c_per_s
            # Compare against an end time with a margin, and never sleep less than 1 ms:
            # a remainder below the clock's float resolution would not move time at all.
            while (remaining_s := duration_s - (self.clock.now_s() - t_start)) > 1e-3:
                walked = (duration_s - remaining_s) * rate_c_per_s
                setpoint = start_c + np.sign(target_c - start_c) * walked
                self.inst.chamber.set_setpoint_c(round(float(setpoint), 2))
                self.clock.sleep(max(min(self.policy.poll_s, remaining_s), 1e-3))
                self.poll_chamber()
        self.inst.chamber.set_setpoint_c(target_c)
        self.machine.soak()
        self.machine.stable()
        if journal_done:
            self.journal.append(JournalEvent.STEP_COMPLETED, step_id=step.step_id, attempt=1,
                                ramp_s=self.clock.now_s() - t_start,
                                **self.completed_fields(step))

    def soak(self, step: PlanStep, journal_done: bool = True) -> None:
        """Wait until the chamber stays within ±tolerance for the hold time, or fault."""
        self.machine.ramp()
        self.journal.append(JournalEvent.STEP_STARTED, step_id=step.step_id, kind=StepKind.SOAK,
                            setpoint_c=step.setpoint_c, attempt=1)
        self.machine.soak()
        t_start = self.clock.now_s()
        t_in_band: float | None = None
        while True:
            temp_c = self.poll_chamber()
            now = self.clock.now_s()
            if abs(temp_c - step.setpoint_c) <= step.tolerance_c:
                t_in_band = now if t_in_band is None else t_in_band
                if now - t_in_band >= step.hold_s:
                    break
            else:
                t_in_band = None
            if now - t_start > step.max_wait_s:
                raise SoakTimeoutError(
                    f"chamber: soak at {step.setpoint_c:g} °C did not stabilise within "
                    f"±{step.tolerance_c:g} °C for {step.hold_s:g} s after waiting "
                    f"{step.max_wait_s:g} s (last reading {temp_c:.2f} °C)")
            self.clock.sleep(min(self.policy.poll_s, max(step.hold_s / 4, 0.1)))
        self.machine.stable()
        if journal_done:
            self.journal.append(JournalEvent.STEP_COMPLETED, step_id=step.step_id, attempt=1,
                                soak_s=self.clock.now_s() - t_start,
                                **self.completed_fields(step))

    def poll_chamber(self) -> float:
        status = self.inst.chamber.read_status()
        if status.alarm:
            raise RunFaultError(f"chamber: alarm at {status.temperature_c:.2f} °C "
                                f"({status.detail or 'no detail'})")
        self.chamber_c = status.temperature_c
        self.progress.update(chamber_c=status.temperature_c, elapsed_s=self.elapsed_s())
        return status.temperature_c

    def set_table_rate(self, rate_dps: float, accel_dps2: float | None = None,
                        settle_s: float = 0.0, *, exact: bool = False) -> None:
        """Command a rate, wait (on the clock) until the table reads it back, then settle.

        A table already reading the rate within the at-rate band is left alone, unless
        ``exact``: a threshold increment (0.01 deg/s) lies inside that band (0.05 deg/s),
        so it is commanded whenever it is not the rate this run last demanded.
        """
        table = self.inst.table
        current = table.read_rate_dps()
        unchanged = not exact or self._demand_dps == rate_dps
        if unchanged and abs(current - rate_dps) <= self.rate_band(rate_dps):
            if self._at_rate is None or abs(self._at_rate[0] - rate_dps) > self.rate_band(rate_dps):
                self._at_rate = (rate_dps, time.monotonic())
            return
        self._at_rate = None
        if not table.interlock_closed():
            raise RunFaultError("table: interlock open; refusing to command motion")
        self.machine.spin()
        if accel_dps2:
            table.set_acceleration_limit_dps2(accel_dps2)
        table.set_rate_dps(rate_dps)
        self._demand_dps = rate_dps
        accel = accel_dps2 or 10.0
        expected_s = abs(rate_dps - current) / accel
        deadline = self.clock.now_s() + self.policy.spin_timeout_factor * expected_s + 10.0
        while True:
            reading = table.read_rate_dps()
            self.table_dps = reading
            if abs(reading - rate_dps) <= self.rate_band(rate_dps):
                self._at_rate = (rate_dps, time.monotonic())
                break
            if self.clock.now_s() > deadline:
                raise RunFaultError(f"table: did not reach {rate_dps:g} deg/s "
                                    f"(reads {reading:g} deg/s) in time")
            if not table.interlock_closed():
                raise RunFaultError("table: interlock opened while spinning")
            self.clock.sleep(max(0.05, min(expected_s / 5, 1.0)))
        self.progress.update(table_dps=reading, elapsed_s=self.elapsed_s())
        if settle_s > 0:
            self.machine.settle()
            self.clock.sleep(settle_s)
        self.machine.settled()

    def forget_demand(self) -> None:
        """The table was stopped behind our back (a pause): the next exact rate is commanded."""
        self._demand_dps = None
        self._at_rate = None

    def at_rate_since_wall_s(self) -> float | None:
        """Wall (monotonic) time the table was last confirmed at its present rate, if known.

        Kept while the table stays at that rate (a repeated attempt, a static
        step after a static step), so frames the gyro sampled since then are
        this rate's data; a new demand forgets it until the readback confirms.
        """
        return None if self._at_rate is None else self._at_rate[1]

    def rate_band(self, rate_dps: float) -> float:
        return self.policy.rate_tolerance_dps + 1e-3 * abs(rate_dps)
