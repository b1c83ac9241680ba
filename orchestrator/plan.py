"""The expanded plan: a procedure flattened into the ordered steps a run executes.

The run engine executes these steps one by one and its journal records each
``step_id`` as completed, so ids must be stable: the same procedure always
expands to the same ids, and a resumed run skips exactly the completed ones.
Each step also carries the labels the analysis needs (temperature step, test,
signed rate, direction, revolutions) and an expected duration, so ``gyrocal
plan`` can print an ETA before anything moves.

Durations are estimates: a ramp takes |ΔT| / ramp rate, a table rate change
|Δω| / acceleration, a soak its hold time (its worst case is ``max_wait``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gyrocal.errors import BadInput
from gyrocal.instruments.table.acutrol_protocol import commanded_rate_dps
from gyrocal.orchestrator.procedure import (
    AllanTest,
    FrequencyResponseTest,
    MagneticTest,
    MountingSpec,
    Procedure,
    RateLimitTest,
    StaticTest,
    SweepTest,
    TableInterferenceTest,
    TemperatureStep,
    TestKind,
    ThresholdTest,
    TiltLinearityTest,
    TurnOnRepeatabilityTest,
    TurnOnTest,
)
from gyrocal.orchestrator.safe_state import table_safe_text
from gyrocal.orchestrator.table_synthesis import REST_BEFORE_SYNTHESIS_S
from gyrocal.orchestrator.turn_on import FIRST_FRAME_TIMEOUT_S
from gyrocal.record.step_kind import StepKind
from gyrocal.units import format_duration, format_hms, format_number

ASSUMED_START_TEMP_C = 25.0   # chamber temperature at the start when the station does not say
#: What the ETA allows for a remount: an operator turning the hexahedron fixture and
#: confirming, then the mount check's short turn of the table (a dry run takes seconds).
REMOUNT_EXPECTED_S = 300.0


@dataclass(frozen=True)
class PlanStep:
    step_id: str                # e.g. "T03.sf.+100dps"; stable across expansions
    kind: StepKind
    source: str                 # where it comes from in the procedure, e.g. "sequence[2].tests[1]"
    temp_index: int             # index into the procedure's sequence (T03 is temp_index 2)
    test_index: int | None      # index into that step's tests; None for ramp and soak
    repeat: int                 # 1-based repeat of the test
    setpoint_c: float           # chamber setpoint during the step
    rate_dps: float             # signed table rate during the step; 0 at rest
    direction: str              # "+" or "-" for dwells, "" at rest
    accel_dps2: float | None    # table acceleration used to reach rate_dps
    settle_s: float             # wait after reaching rate_dps, before logging
    duration_s: float           # ramp: estimated ramp time; soak: hold time; others: logged time
    transition_s: float         # estimated table acceleration/deceleration before the step
    expected_s: float           # transition + settle + duration: what the ETA adds up
    max_s: float                # worst case (a soak may wait up to max_wait)
    start_s: float              # expected start, seconds after the run starts
    ramp_c_per_min: float | None = None
    # The soak criterion of the temperature step: stable within ±tolerance_c for hold_s,
    # else fault after max_wait_s. Every step carries it, so a resumed run can re-soak.
    tolerance_c: float | None = None
    hold_s: float | None = None
    max_wait_s: float | None = None
    revolutions: float | None = None    # table revolutions during the dwell (whole with min_revolutions)
    label: str | None = None
    mounting: str | None = None         # the fixture mounting (IMU procedures); None for one axis
    # threshold steps: the base rate the increment is added to, and the test's decision
    # criteria (the report needs them; plan.json is all it reads)
    base_rate_dps: float | None = None
    confidence: float | None = None
    max_error_fraction: float | None = None
    # rate-limit steps: the linearity criterion and how many lowest rates make the fit
    linearity_tolerance_pct: float | None = None
    fit_rates: int | None = None
    # frequency-response steps: the sinusoid the table turns (peak rate, frequency) and the
    # frequency the report states the phase at
    freq_hz: float | None = None
    amplitude_dps: float | None = None
    phase_at_hz: float | None = None
    # magnetic steps: the coil's field along its axis during the step, tesla (signed)
    field_t: float | None = None
    # tilt steps: the table angle (position mode, axis horizontal), deg
    angle_deg: float | None = None
    # turn-on steps: the stated band of the settled bias, deg/h (off time: settle_s)
    band_dph: float | None = None
    # turn-on cycles (repeatability): the cool-down the unit is off (part of settle_s)
    off_s: float | None = None


@dataclass(frozen=True)
class Plan:
    procedure_name: str
    procedure_file: str
    station_name: str
    start_temp_c: float
    steps: tuple[PlanStep, ...]
    total_s: float              # expected time from start to the end of the last step
    max_total_s: float          # if every soak waits its maximum
    finish_s: float             # afterwards: table stop and chamber back to its safe setpoint
    table_hold: bool = False    # the safe state holds the table under servo (horizontal axis)

    def index_of(self, step_id: str) -> int:
        for index, step in enumerate(self.steps):
            if step.step_id == step_id:
                return index
        raise KeyError(f"no step {step_id!r} in the plan of {self.procedure_file}")

    def remaining_s(self, step_id: str) -> float:
        """Expected time from the start of ``step_id`` to the end of the plan (resume ETA)."""
        return self.total_s - self.steps[self.index_of(step_id)].start_s

    def logged_s(self) -> float:
        """Total gyro data logged for analysis (static, allan and dwell steps)."""
        return sum(s.duration_s for s in self.steps if s.kind.logs_data)


def _rate_tag(rate_dps: float) -> str:
    return f"{rate_dps:+g}dps"


def _test_tags(step: TemperatureStep) -> list[str]:
    """``sf``, ``static``, ``allan``; numbered (``sf1``, ``sf2``) when a kind repeats in a step."""
    base = {TestKind.SF_SWEEP: "sf", TestKind.STATIC: "static", TestKind.ALLAN: "allan",
            TestKind.TABLE_INTERFERENCE: "interference", TestKind.THRESHOLD: "thr",
            TestKind.RATE_LIMIT: "lim", TestKind.FREQUENCY_RESPONSE: "freq",
            TestKind.MAGNETIC: "mag", TestKind.TILT_LINEARITY: "tilt", TestKind.TURN_ON: "turnon",
            TestKind.TURN_ON_REPEATABILITY: "rep"}
    kinds = [base[test.kind] for test in step.tests]
    seen: dict[str, int] = {}
    tags = []
    for kind in kinds:
        seen[kind] = seen.get(kind, 0) + 1
        tags.append(f"{kind}{seen[kind]}" if kinds.count(kind) > 1 else kind)
    return tags


def dwell_for_rate(test: SweepTest, rate_dps: float) -> tuple[float, float]:
    """(dwell_s, revolutions) at ``rate_dps``.

    With ``min_revolutions`` the dwell is the first whole number of revolutions
    that lasts at least ``dwell_s`` and is at least ``min_revolutions``, so
    orientation-dependent errors (Earth rate, unbalance) average out.
    """
    period_s = 360.0 / abs(rate_dps)
    turns = test.dwell_s / period_s
    if test.min_revolutions is None:
        return test.dwell_s, turns
    whole = max(test.min_revolutions, math.ceil(turns - 1e-9))
    return whole * period_s, float(whole)


class _Expander:
    def __init__(self, procedure: Procedure, start_temp_c: float) -> None:
        self.procedure = procedure
        self.steps: list[PlanStep] = []
        self.clock_s = 0.0
        self.max_clock_s = 0.0
        self.chamber_c = start_temp_c
        self.table_dps = 0.0
        self.last_accel_dps2 = self._stop_accel()

    def _stop_accel(self) -> float:
        proc = self.procedure
        return proc.defaults.accel_dps2 or proc.safety.table.max_accel_dps2

    def add(
        self,
        *,
        duration_s: float,
        rate_dps: float = 0.0,
        accel_dps2: float | None = None,
        settle_s: float = 0.0,
        max_duration_s: float | None = None,
        **labels: object,
    ) -> None:
        """Append a step, timing the table's move from the previous step's rate."""
        accel = accel_dps2 or self.last_accel_dps2
        transition = abs(rate_dps - self.table_dps) / accel
        expected = transition + settle_s + duration_s
        worst = transition + settle_s + (duration_s if max_duration_s is None else max_duration_s)
        step = PlanStep(
            rate_dps=rate_dps, accel_dps2=accel, settle_s=settle_s, duration_s=duration_s,
            transition_s=transition, expected_s=expected, max_s=worst, start_s=self.clock_s,
            **labels,  # type: ignore[arg-type]
        )
        self.steps.append(step)
        self.clock_s += expected
        self.max_clock_s += worst
        self.table_dps = rate_dps
        self.last_accel_dps2 = accel

    def temperature_step(self, index: int, step: TemperatureStep, id_prefix: str = "",
                         mounting: str | None = None) -> None:
        """Ramp, soak and the tests of one temperature (in one mounting, if any)."""
        self.conditions(index, step, id_prefix)
        self.tests(index, step, id_prefix, mounting)

    def conditions(self, index: int, step: TemperatureStep, id_prefix: str = "") -> None:
        prefix = f"{id_prefix}T{index + 1:02d}"
        source = f"sequence[{index}]"
        common = self._common(index, step)
        ramp_s = abs(step.setpoint_c - self.chamber_c) / step.ramp_c_per_min * 60.0
        self.add(step_id=f"{prefix}.ramp", kind=StepKind.RAMP, source=source, test_index=None, repeat=1,
                 direction="",
                 duration_s=ramp_s, ramp_c_per_min=step.ramp_c_per_min, **common)
        self.chamber_c = step.setpoint_c
        self.add(step_id=f"{prefix}.soak", kind=StepKind.SOAK, source=f"{source}.soak", test_index=None,
                 repeat=1, direction="", duration_s=step.soak.hold_s,
                 max_duration_s=step.soak.max_wait_s, **common)

    @staticmethod
    def _common(index: int, step: TemperatureStep) -> dict:
        soak = step.soak
        criterion = dict(tolerance_c=soak.tolerance_c, hold_s=soak.hold_s, max_wait_s=soak.max_wait_s)
        return dict(temp_index=index, setpoint_c=step.setpoint_c, label=step.label, **criterion)

    def tests(self, index: int, step: TemperatureStep, id_prefix: str = "",
              mounting: str | None = None) -> None:
        prefix = f"{id_prefix}T{index + 1:02d}" if mounting is None or id_prefix else (
            f"T{index + 1:02d}.M{mounting}")
        source = f"sequence[{index}]"
        common = dict(self._common(index, step), mounting=mounting)
        for test_index, (test, tag) in enumerate(zip(step.tests, _test_tags(step), strict=True)):
            for repeat in range(1, test.repeats + 1):
                suffix = f".r{repeat}" if test.repeats > 1 else ""
                base = dict(common, source=f"{source}.tests[{test_index}]",
                            test_index=test_index, repeat=repeat, label=test.label or step.label)
                expand = next((_EXPANDERS[cls] for cls in type(test).__mro__
                               if cls in _EXPANDERS), _Expander.sweep)
                expand(self, prefix, tag, suffix, test, base)

    def held(self, prefix: str, tag: str, suffix: str, test: StaticTest | AllanTest,
             base: dict) -> None:
        self.add(step_id=f"{prefix}.{tag}{suffix}", kind=StepKind(test.kind), direction="",
                 duration_s=test.duration_s, settle_s=test.settle_s, **base)

    def interference(self, prefix: str, tag: str, suffix: str, test: TableInterferenceTest,
                     base: dict) -> None:
        # the drive powered at zero rate, then off: analysis/environment/interference.py pairs them
        for half, kind in (("powered", StepKind.STATIC), ("off", StepKind.DRIVE_OFF)):
            self.add(step_id=f"{prefix}.{tag}{suffix}.{half}", kind=kind, direction="",
                     duration_s=test.duration_s, settle_s=test.settle_s, **base)

    def magnetic(self, prefix: str, tag: str, suffix: str, test: MagneticTest,
                 base: dict) -> None:
        # +B, 0, -B: reports/sections/magnetic.py regresses the bias on the field
        for half, field_t in (("pos", test.field_t), ("zero", 0.0), ("neg", -test.field_t)):
            self.add(step_id=f"{prefix}.{tag}{suffix}.{half}", kind=StepKind.MAGNETIC,
                     direction="", duration_s=test.duration_s, settle_s=test.settle_s,
                     field_t=field_t, **base)

    def tilt(self, prefix: str, tag: str, suffix: str, test: TiltLinearityTest,
             base: dict) -> None:
        # each angle point, then the zero-stability hold at 0 (the table as the
        # indexing head; reports/sections/tilt.py fits them)
        for angle in test.angles_deg:
            self.add(step_id=f"{prefix}.{tag}{suffix}.{angle:+g}deg",
                     kind=StepKind.TILT, direction="", duration_s=test.dwell_s,
                     settle_s=test.settle_s, angle_deg=angle, **base)
        self.add(step_id=f"{prefix}.{tag}{suffix}.zero", kind=StepKind.TILT,
                 direction="", duration_s=test.zero_stability_s,
                 settle_s=test.settle_s, angle_deg=0.0, **base)

    def turn_on(self, prefix: str, tag: str, suffix: str, test: TurnOnTest,
                base: dict) -> None:
        # settle: the time the unit is off before the output-on (the ETA adds it)
        self.add(step_id=f"{prefix}.{tag}{suffix}", kind=StepKind.TURN_ON,
                 direction="", duration_s=test.duration_s, settle_s=test.off_s,
                 max_duration_s=test.duration_s + FIRST_FRAME_TIMEOUT_S,
                 band_dph=test.band_dph, **base)

    def turn_on_cycles(self, prefix: str, tag: str, suffix: str,
                       test: TurnOnRepeatabilityTest, base: dict) -> None:
        # each cycle: off, on, settle after the first frame, log
        for cycle in range(1, test.cycles + 1):
            self.add(step_id=f"{prefix}.{tag}{suffix}.c{cycle}",
                     kind=StepKind.TURN_ON_CYCLE, direction="",
                     duration_s=test.duration_s,
                     settle_s=test.off_s + test.settle_s, off_s=test.off_s,
                     max_duration_s=test.duration_s + FIRST_FRAME_TIMEOUT_S, **base)

    def remount(self, step_id: str, spec: MountingSpec, index: int, step: TemperatureStep) -> None:
        """An operator step: table stopped, the fixture turned to ``spec``, then checked."""
        self.add(step_id=step_id, kind=StepKind.REMOUNT, source=f"mountings[{spec.name}]",
                 test_index=None, repeat=1, direction="", duration_s=REMOUNT_EXPECTED_S,
                 label=spec.instruction, mounting=spec.name, temp_index=index,
                 setpoint_c=self.chamber_c if self.steps else step.setpoint_c,
                 tolerance_c=step.soak.tolerance_c, hold_s=step.soak.hold_s,
                 max_wait_s=step.soak.max_wait_s)

    def sweep(self, prefix: str, tag: str, suffix: str, test: SweepTest, base: dict) -> None:
        signs = {"both": (1.0, -1.0), "positive": (1.0,), "negative": (-1.0,)}[test.directions]
        for magnitude in test.rates_dps:
            dwell_s, turns = dwell_for_rate(test, magnitude)
            for sign in signs:
                rate = sign * magnitude
                self.add(step_id=f"{prefix}.{tag}.{_rate_tag(rate)}{suffix}", kind=StepKind.DWELL,
                         rate_dps=rate, direction="+" if sign > 0 else "-",
                         accel_dps2=test.accel_dps2, settle_s=test.settle_s, duration_s=dwell_s,
                         revolutions=turns, **base)

    def threshold(self, prefix: str, tag: str, suffix: str, test: ThresholdTest,
                  base: dict) -> None:
        """base, base+δ₁, base, base+δ₂, …, base: each increment between two base dwells.

        Ids: ``T01.thr.+0dps.ref0``, ``T01.thr.+0dps.+0.01dps``, ``T01.thr.+0dps.ref1``…
        """
        criteria = dict(confidence=test.confidence, max_error_fraction=test.max_error_fraction)
        for base_rate in test.base_rates_dps:
            head = f"{prefix}.{tag}.{_rate_tag(base_rate)}"
            common = dict(base, base_rate_dps=base_rate, accel_dps2=test.accel_dps2,
                          settle_s=test.settle_s, duration_s=test.dwell_s, **criteria)
            for index, increment in enumerate(test.increments_dps):
                self.add(step_id=f"{head}.ref{index}{suffix}", kind=StepKind.THRESHOLD,
                         rate_dps=base_rate, direction="", **common)
                rate = commanded_rate_dps(base_rate + increment)
                self.add(step_id=f"{head}.{_rate_tag(increment)}{suffix}", kind=StepKind.THRESHOLD,
                         rate_dps=rate, direction="+", **common)
            self.add(step_id=f"{head}.ref{len(test.increments_dps)}{suffix}",
                     kind=StepKind.THRESHOLD, rate_dps=base_rate, direction="", **common)

    def rate_limit(self, prefix: str, tag: str, suffix: str, test: RateLimitTest,
                   base: dict) -> None:
        """Each way in turn, the rates walked up: ``T01.lim.+50dps`` … then ``T01.lim.-50dps`` …"""
        signs = {"both": (1.0, -1.0), "positive": (1.0,), "negative": (-1.0,)}[test.directions]
        common = dict(base, accel_dps2=test.accel_dps2, settle_s=test.settle_s,
                      duration_s=test.dwell_s,
                      linearity_tolerance_pct=test.linearity_tolerance_pct,
                      fit_rates=test.fit_rates)
        for sign in signs:
            for magnitude in test.rates_dps:
                rate = sign * magnitude
                self.add(step_id=f"{prefix}.{tag}.{_rate_tag(rate)}{suffix}",
                         kind=StepKind.RATE_LIMIT, rate_dps=rate,
                         direction="+" if sign > 0 else "-", **common)

    def frequency_response(self, prefix: str, tag: str, suffix: str,
                           test: FrequencyResponseTest, base: dict) -> None:
        """One step per frequency, centred at rest: ``T01.freq.2Hz`` … (settle: the rest
        before synthesis, then whole periods)."""
        for freq in test.frequencies_hz:
            self.add(step_id=f"{prefix}.{tag}.{freq:g}Hz{suffix}",
                     kind=StepKind.FREQUENCY_RESPONSE, rate_dps=0.0, direction="",
                     settle_s=REST_BEFORE_SYNTHESIS_S + test.settle_s(freq), duration_s=test.duration_s(freq),
                     freq_hz=freq, amplitude_dps=test.amplitude_dps,
                     phase_at_hz=test.phase_at_hz, **base)

    def finish(self) -> float:
        """Stop the table, then bring the chamber to its safe setpoint (if it has one)."""
        proc = self.procedure
        stop_s = abs(self.table_dps) / self.last_accel_dps2
        safe = proc.station.chamber.safe_state
        if safe.action != "setpoint" or safe.setpoint_c is None:
            return stop_s
        ramp = proc.defaults.ramp_c_per_min or proc.safety.chamber.max_ramp_c_per_min
        return stop_s + abs(safe.setpoint_c - self.chamber_c) / ramp * 60.0


#: How each kind of test in a temperature step becomes plan steps (a sweep when not listed).
_EXPANDERS = {
    StaticTest: _Expander.held,
    AllanTest: _Expander.held,
    TableInterferenceTest: _Expander.interference,
    MagneticTest: _Expander.magnetic,
    TiltLinearityTest: _Expander.tilt,
    TurnOnTest: _Expander.turn_on,
    TurnOnRepeatabilityTest: _Expander.turn_on_cycles,
    ThresholdTest: _Expander.threshold,
    RateLimitTest: _Expander.rate_limit,
    FrequencyResponseTest: _Expander.frequency_response,
}


def expand_plan(procedure: Procedure, start_temp_c: float | None = None) -> Plan:
    """Flatten ``procedure`` into executable steps with expected durations and ETA.

    ``start_temp_c`` is where the chamber starts (for the first ramp); by
    default the simulated ambient, else :data:`ASSUMED_START_TEMP_C`.
    """
    if start_temp_c is None:
        sim = procedure.station.simulation
        start_temp_c = sim.chamber.ambient_c if sim is not None else ASSUMED_START_TEMP_C
    expander = _Expander(procedure, start_temp_c)
    sequence = procedure.sequence
    if not procedure.mountings:
        for index, step in enumerate(sequence):
            expander.temperature_step(index, step)
    elif procedure.mounting_order == "temperatures_inside":
        # MX.remount, MX.T01.ramp … MX.T05.sf.-200dps, MY.remount, …
        for spec in procedure.mountings:
            expander.remount(f"M{spec.name}.remount", spec, 0, sequence[0])
            for index, step in enumerate(sequence):
                expander.temperature_step(index, step, id_prefix=f"M{spec.name}.",
                                          mounting=spec.name)
    else:
        # T01.ramp, T01.soak, T01.MX.remount, T01.MX.sf.+10dps … T01.MZ.…, T02.ramp, …
        for index, step in enumerate(sequence):
            expander.conditions(index, step)
            for spec in procedure.mountings:
                expander.remount(f"T{index + 1:02d}.M{spec.name}.remount", spec, index, step)
                expander.tests(index, step, mounting=spec.name)
    ids = [s.step_id for s in expander.steps]
    if len(set(ids)) != len(ids):   # cannot happen for a validated procedure; journals depend on it
        raise AssertionError(f"duplicate step ids in the plan of {procedure.file}")
    _check_eta(procedure, expander.clock_s)
    return Plan(
        procedure_name=procedure.name,
        procedure_file=procedure.file,
        station_name=procedure.station.name,
        start_temp_c=start_temp_c,
        steps=tuple(expander.steps),
        total_s=expander.clock_s,
        max_total_s=expander.max_clock_s,
        finish_s=expander.finish(),
        table_hold=procedure.station.table.holds_axis_when_safe,
    )


def _check_eta(procedure: Procedure, eta_s: float) -> None:
    """Refuse a plan longer than the procedure allows: such ETAs come from typos (a ramp of
    1e-9 °C/min gave 327 million hours), so validate, plan and run all say so before anything moves."""
    if eta_s <= procedure.max_duration_s:
        return
    allowed = f"{procedure.max_duration_s / 86400:g} days"
    if procedure.max_duration_declared:
        why = f"longer than its declared max_duration: {allowed}"
    else:
        why = (f"longer than {allowed}, the most a procedure may take unless it declares "
               "max_duration: (top level)")
    raise BadInput(f"{procedure.file}: the plan's ETA is {eta_s / 86400:,.1f} days "
                   f"({eta_s / 3600:,.0f} h), {why}; check the ramps, accelerations, rates and "
                   "durations")


def _remount_line(plan: Plan) -> list[str]:
    """How often the operator must come to the table: each remount waits for `gyrocal confirm`."""
    remounts = [s for s in plan.steps if s.kind == StepKind.REMOUNT]
    if not remounts:
        return []
    names = list(dict.fromkeys(s.mounting for s in remounts))
    return [f"{len(remounts)} remounts by the operator ({len(names)} mountings: "
            f"{', '.join(str(n) for n in names)}); the run waits at each for `gyrocal confirm`"]


def format_plan(plan: Plan) -> str:
    """The plan as a fixed-width table an operator can check before starting the night."""
    header = ("#", "step", "kind", "setpoint", "rate", "move+settle", "logged/hold", "expected",
              "starts at")
    rows = []
    for number, step in enumerate(plan.steps, start=1):
        if step.kind == StepKind.RAMP:
            move = f"{format_number(step.ramp_c_per_min)} °C/min"
            logged = "-"
        else:
            move = format_duration(step.transition_s + step.settle_s)
            logged = format_duration(step.duration_s)
        if step.kind == StepKind.REMOUNT:
            move, logged = "operator", "-"
        rate = "-" if step.kind in (StepKind.RAMP, StepKind.SOAK, StepKind.REMOUNT) else (
            f"{step.rate_dps:+g} deg/s" if step.rate_dps else "0 deg/s")
        if step.kind == StepKind.DWELL and step.revolutions is not None:
            rate += f" ({step.revolutions:.3g} rev)"
        if step.kind == StepKind.MAGNETIC and step.field_t is not None:
            rate += f" (coil {step.field_t * 1e3:+g} mT)"
        if step.kind == StepKind.TILT and step.angle_deg is not None:
            rate = f"at {step.angle_deg:+g}° (position)"
        rows.append((str(number), step.step_id, step.kind, f"{step.setpoint_c:g} °C", rate, move,
                     logged, format_duration(step.expected_s), format_hms(step.start_s)))
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    lines = [
        f"Procedure: {plan.procedure_name} ({plan.procedure_file})",
        f"Station:   {plan.station_name}",
        f"Start:     chamber at {plan.start_temp_c:g} °C",
        "",
        "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip(),
        "  ".join("-" * w for w in widths),
    ]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in rows]
    lines += [
        "",
        f"{len(plan.steps)} steps; gyro data logged {format_duration(plan.logged_s())}",
        *_remount_line(plan),
        f"ETA {format_duration(plan.total_s)} (worst case {format_duration(plan.max_total_s)} "
        "if every soak waits its maximum), then "
        f"{format_duration(plan.finish_s)} to return to the safe state",
        f"Safe state (a fault, the end): {table_safe_text(plan.table_hold)}",
    ]
    return "\n".join(lines)
