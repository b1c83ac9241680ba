"""Run folder → report/results.json + report/report.html, hashes journalled.

The report must be rebuildable by QA from the run folder alone, so every
input comes from it: plan.json (steps, acceptance, unit, station), the
journal (which chunks belong to completed attempts) and the sample chunks.
Each step is read once, reduced to its mean at once and dropped, except the
longest static hold, kept for the Allan curve — an overnight run is far
larger than memory needs to be.

Single numbers where several temperatures exist (documented in results.json
``definitions`` as well):

- ``scale_factor_ls``: the LS line at the temperature closest to 25 °C
  (:data:`REFERENCE_TEMP_C`, the gyro-model reference temperature; a tie goes to the lower);
- ``nonlinearity``: the worst (largest) rms_pct and max_ppm_fs over temperatures;
- ``asymmetry_ppm``: the value with the largest magnitude, sign kept;
- ``bias``: per temperature from the static/allan holds there (mean output
  / SF at that temperature, Earth rate along a vertical axis removed with the
  station latitude); from the sweep's LS intercept where no hold exists;
- ``allan``: the longest static/allan hold, input-referred (÷ nominal scale
  factor, which is output units per deg/s, ×3600 → deg/h).

A figure that cannot be computed is null with a reason in ``notes``.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.analysis.allan.summary import allan_curve, fit_curve
from gyrocal.analysis.rate import rate_limits
from gyrocal.analysis.rate.dwell import Dwell, SegmentDrift, dwell_mean, segment_drift
from gyrocal.analysis.rate.scale_factor import ScaleFactorResult, analyze_scale_factor
from gyrocal.analysis.rate.threshold import ThresholdDwell, ThresholdResults, threshold_section
from gyrocal.analysis.thermal import bias as bias_mod
from gyrocal.analysis.thermal import compensation as comp
from gyrocal.metrology.decision import instrument_findings, overall_verdict
from gyrocal.metrology.gum import batch_mean_sem
from gyrocal.metrology.metrics import Need
from gyrocal.metrology.sanity import check_physics
from gyrocal.metrology.uncertainty import MeanU
from gyrocal.models.rate_units import output_to_dph
from gyrocal.record.atomic import write_bytes_atomic
from gyrocal.record.journal import Journal, JournalEvent, sha256_bytes
from gyrocal.record.logged_steps import HOLD_KINDS, completed_attempts, longest_hold
from gyrocal.record.plan_record import PlanRecord, RecordedStep, load_plan_record
from gyrocal.record.run_folder import RunFolder, identified_instruments
from gyrocal.record.samples import RunSamples
from gyrocal.record.signing import Signer
from gyrocal.record.step_kind import StepKind
from gyrocal.record.strays import set_aside
from gyrocal.reports.acceptance import evaluate_acceptance
from gyrocal.reports.html_report import render_html
from gyrocal.reports.results import (
    Results,
    TestSections,
    UnitUnderTest,
    finite_or_none,
    results_bytes,
)
from gyrocal.reports.run_info import (
    IDENTITY_KEYS,
    InputRecord,
    InstrumentRecord,
    JournalSummary,
    Provenance,
    RunInfo,
    StationRecord,
    StepRecord,
    run_mode,
)
from gyrocal.reports.sections import frequency as frequency_section
from gyrocal.reports.sections.allan import AllanSection
from gyrocal.reports.sections.bias import BiasEntry, BiasResults, BiasSource
from gyrocal.reports.sections.compensation import CompensationResults, Tables
from gyrocal.reports.sections.imu import ImuResults, imu_section
from gyrocal.reports.sections.interference import interference_section
from gyrocal.reports.sections.magnetic import magnetic_section
from gyrocal.reports.sections.sweep import ScaleFactorEntry, SweepResults
from gyrocal.reports.sections.tilt import tilt_section
from gyrocal.reports.sections.turn_on import (
    CycleRecord,
    RepeatabilityResults,
    TurnOnRecord,
    TurnOnResults,
    repeatability_section,
    turn_on_section,
)
from gyrocal.reports.sections.uncertainty import StepMean, uncertainty_budget

REFERENCE_TEMP_C = 25.0
REPORT_DIR = "report"
RESULTS_FILE = "report/results.json"
HTML_FILE = "report/report.html"
_READ_COLUMNS = ["gyro", "sensor_temp_c", "chamber_temp_c"]
_JOURNAL_SHOWN = (JournalEvent.RETRY, JournalEvent.FAULT, JournalEvent.STEP_BAD,
                  JournalEvent.INTERRUPTED, JournalEvent.SAFE_STATE, JournalEvent.RESUMED,
                  JournalEvent.RESTORE_CONDITIONS)


@dataclass
class StepSummary:
    """One logged step reduced: mean output over the samples used, measured temperatures."""

    step: RecordedStep
    output_mean: float
    output_std: float
    n_used: int
    n_logged: int
    sensor_temp_c: float | None
    chamber_temp_c: float | None
    trimmed_to_revolutions: float | None = None
    #: type A standard uncertainty of ``output_mean`` (batch means) and its dof
    output_sem: float = math.nan
    sem_dof: float = math.nan
    #: a rate dwell's worst part against the rest (sanity.py judges it)
    drift: SegmentDrift | None = None


@dataclass
class RunData:
    folder: RunFolder
    manifest: dict[str, Any]
    plan: dict[str, Any]          # plan.json as written (record.raw): the parts sections copy
    events: list[dict[str, Any]]
    record: PlanRecord            # plan.json, typed (the steps, rate, mountings, site)
    steps: list[StepSummary] = field(default_factory=list)
    allan_step: StepSummary | None = None
    allan_output: np.ndarray | None = None


# -- reading ------------------------------------------------------------------------------

def _good_columns(data: RunData, step_id: str, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """A step's counted attempt, the named columns, the samples the gyro flagged left out."""
    return dict(RunSamples(data.folder.path, data.events).step(step_id, names).columns)


def _unit_under_test_mountings(record: PlanRecord) -> set[str]:
    """The mountings whose up axis is the station's unit-under-test axis, + sign.

    In a multi-axis IMU run the single-axis sections (scale factor, bias,
    Allan…) are those of that axis, from the mounting that puts it up; the
    three-axis matrix is the ``imu`` section.
    """
    axis = "xyz".index(record.unit_under_test_axis)
    return {m.name for m in record.mountings if m.up_axis == axis and m.sign > 0}


def _mean_or_none(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else None


def _whole_revolutions(step: dict[str, Any]) -> int | None:
    """Revolutions to keep when the procedure asked for whole turns (min_revolutions)."""
    turns = step.revolutions
    if step.kind != StepKind.DWELL or turns is None or not float(turns).is_integer():
        return None
    return int(turns) if turns >= 1 else None


def _reduce_dwell(output: np.ndarray, step: dict[str, Any], fs_hz: float,
                  notes: list[str]) -> tuple[float, float, int, float | None]:
    turns = _whole_revolutions(step)
    if turns is not None:
        for wanted in (turns, "all"):
            try:
                stats = dwell_mean(output, fs_hz, 0.0, step.rate_dps, revolutions=wanted)
            except ValueError:
                continue
            kept = stats.n_samples * abs(step.rate_dps) / fs_hz / 360.0
            return stats.mean, stats.std, stats.n_samples, round(kept, 6)
        notes.append(f"step {step.step_id}: fewer samples than one whole revolution; "
                     "the mean uses every logged sample")
    stats = dwell_mean(output, fs_hz, 0.0)
    return stats.mean, stats.std, stats.n_samples, None


def _mean_sem(kept: np.ndarray, step_id: str, notes: list[str]) -> tuple[float, float]:
    """Type A u of a step mean: batch means (correlated noise), σ/√n only for tiny steps."""
    try:
        return batch_mean_sem(kept)
    except ValueError:
        notes.append(f"step {step_id}: {kept.size} samples, too few for batch means; its mean's "
                     "uncertainty is σ/√n (white noise assumed)")
        if kept.size < 2:
            return math.nan, math.nan
        return float(kept.std(ddof=1) / math.sqrt(kept.size)), float(kept.size - 1)


def read_run(run_dir: Path, notes: list[str]) -> RunData:
    """Read and reduce every completed logged step; keep the longest hold's samples."""
    folder = RunFolder.open(Path(run_dir))
    record = load_plan_record(folder.path)
    data = RunData(folder, folder.read_manifest(), record.raw, folder.journal_events(), record)
    fs_hz = data.record.sample_rate_hz
    plan_steps = {s.step_id: s for s in data.record.steps}
    run_samples = RunSamples(folder.path, data.events)
    hold = longest_hold(data.record.kinds, data.events)
    longest = None if hold is None else hold["step_id"]
    own = _unit_under_test_mountings(data.record)
    for step_id in run_samples.logged:
        step = plan_steps.get(step_id)
        if step is None:
            notes.append(f"step {step_id}: logged but not in plan.json; ignored")
            continue
        if step.mounting is not None and step.mounting not in own:
            continue    # another IMU axis up: only the ``imu`` section uses it
        # good samples only: those the gyro flagged (saturated, in error) are never averaged in
        columns = run_samples.step(step_id, _READ_COLUMNS).columns
        output = columns["gyro"]
        if output.size == 0:
            continue
        if step.kind == StepKind.DWELL:
            mean, std, used, turns = _reduce_dwell(output, step, fs_hz, notes)
        else:
            stats = dwell_mean(output, fs_hz, 0.0)
            mean, std, used, turns = stats.mean, stats.std, stats.n_samples, None
        sem, sem_dof = _mean_sem(output[:used], step_id, notes)
        summary = StepSummary(step, mean, std, used, int(output.size),
                              _mean_or_none(columns["sensor_temp_c"]),
                              _mean_or_none(columns["chamber_temp_c"]), turns, sem, sem_dof)
        if step.kind == StepKind.DWELL:
            summary.drift = segment_drift(output)
        data.steps.append(summary)
        if step_id == longest:
            data.allan_step, data.allan_output = summary, output
    return data


# -- analysis -----------------------------------------------------------------------------

def _weighted_temp(summaries: list[StepSummary], attr: str) -> float | None:
    pairs = [(getattr(s, attr), s.n_used) for s in summaries if getattr(s, attr) is not None]
    if not pairs:
        return None
    return float(sum(v * n for v, n in pairs) / sum(n for _, n in pairs))


def _scale_factor(data: RunData, notes: list[str]) -> list[ScaleFactorEntry]:
    """SF per setpoint temperature, with the measured temperatures and residuals."""
    groups: dict[float, list[StepSummary]] = defaultdict(list)
    for s in data.steps:
        if s.step.kind == StepKind.DWELL:
            groups[s.step.setpoint_c].append(s)
    out = []
    for temp in sorted(groups):
        members = groups[temp]
        dwells = [Dwell(temp, s.step.rate_dps, s.output_mean, s.output_std, s.n_used)
                  for s in members]
        try:
            result = analyze_scale_factor(dwells)
        except ValueError as exc:
            notes.append(f"scale factor at {temp:g} °C not computed: {exc}")
            continue
        full_scale = abs(result.sf) * max(abs(d.rate_dps) for d in dwells)
        residuals = sorted((d.rate_dps, float(res / full_scale * 1e6))
                           for d, res in zip(dwells, result.residuals, strict=True))
        out.append(ScaleFactorEntry(result, _weighted_temp(members, "sensor_temp_c"),
                                    _weighted_temp(members, "chamber_temp_c"), tuple(residuals)))
    return out


def _imu(data: RunData, notes: list[str]) -> ImuResults | None:
    latitude = ((data.plan.get("station") or {}).get("site") or {}).get("latitude_deg")
    return imu_section(data.folder.path, data.record, data.events, float(latitude or 0.0), notes)


def _earth_rate_dph(plan: dict[str, Any], notes: list[str]) -> float:
    latitude = ((plan.get("station") or {}).get("site") or {}).get("latitude_deg")
    if latitude is None:
        notes.append("station site has no latitude_deg: Earth rate is NOT removed from the bias")
        return 0.0
    return bias_mod.earth_rate_vertical_dph(float(latitude))


def _bias(data: RunData, sf_results: list[ScaleFactorResult], nominal_sf: float,
          earth_dph: float, notes: list[str]) -> list[BiasEntry]:
    sf_at = {r.temp_c: r for r in sf_results}
    holds: dict[float, list[StepSummary]] = defaultdict(list)
    for s in data.steps:
        if s.step.kind in HOLD_KINDS:
            holds[s.step.setpoint_c].append(s)
    points = []
    for temp in sorted(set(holds) | set(sf_at)):
        sf_result = sf_at.get(temp)
        sf = sf_result.sf if sf_result is not None else nominal_sf
        if temp in holds:
            members = holds[temp]
            mean = sum(s.output_mean * s.n_used for s in members) / sum(s.n_used for s in members)
            value, source = float(output_to_dph(mean, sf)) - earth_dph, BiasSource.STATIC
            if sf_result is None:
                notes.append(f"bias at {temp:g} °C uses the nominal scale factor {nominal_sf:g} "
                             "(no sweep at that temperature)")
            sensor = _weighted_temp(members, "sensor_temp_c")
        else:
            value = float(output_to_dph(sf_result.bias, sf)) - earth_dph
            source, sensor = BiasSource.SWEEP_INTERCEPT, None
        points.append(BiasEntry(temp, value, source, sensor))
    return points


def _comp_tables(points: list[tuple[float, float]], what: str, notes: list[str]) -> Tables:
    temps = [p[0] for p in points]
    values = [p[1] for p in points]
    tables: dict[str, comp.CompensationTable | None] = {"piecewise_linear": None,
                                                         "polynomial": None}
    if len(points) < 3:
        notes.append(f"{what} compensation: {len(points)} temperature(s); residuals need ≥ 3 "
                     "(the table is the measured points)")
        return tables
    for key, make in (("piecewise_linear", lambda: comp.piecewise_linear(temps, values)),
                      ("polynomial", lambda: comp.polynomial(temps, values,
                                                             degree=min(2, len(points) - 2)))):
        tables[key] = make()
    return tables


def _allan(data: RunData, nominal_sf: float, notes: list[str]) -> AllanSection | None:
    if data.allan_step is None or data.allan_output is None:
        notes.append("allan: no static or allan hold was logged")
        return None
    fs_hz = data.record.sample_rate_hz
    rate_dph = output_to_dph(data.allan_output, nominal_sf)
    step = data.allan_step.step
    try:
        curve = allan_curve(rate_dph, fs_hz)
        fit = fit_curve(curve)
    except ValueError as exc:
        notes.append(f"allan: step {step.step_id} ({rate_dph.size} samples) gives no usable "
                     f"curve/fit: {exc}")
        return None
    return AllanSection(curve, fit, step.step_id, step.setpoint_c, int(rate_dph.size), fs_hz)


def _journal_summary(events: list[dict[str, Any]]) -> JournalSummary:
    shown = [{k: v for k, v in e.items() if k != "prev_sha256"}
             for e in events if e.get("event") in _JOURNAL_SHOWN]
    chunks = [e for e in events if e.get("event") == JournalEvent.CHUNK_WRITTEN]
    digest = hashlib.sha256()
    for e in chunks:
        digest.update(f"{e['path']} {e['sha256']}\n".encode())
    return JournalSummary(
        tuple(shown),
        retries=sum(1 for e in events if e.get("event") == JournalEvent.RETRY),
        faults=sum(1 for e in events if e.get("event") == JournalEvent.FAULT),
        bad_steps=sum(1 for e in events if e.get("event") == JournalEvent.STEP_BAD),
        chunks=len(chunks),
        samples_sha256=digest.hexdigest(),
        event_count=len(events),
        first_wall_time=events[0].get("wall_time") if events else None,
        last_wall_time=events[-1].get("wall_time") if events else None)


def _recorded_identity(data: RunData) -> dict[str, Any]:
    started = next((e for e in data.events if e.get("event") == JournalEvent.RUN_STARTED), {})
    identity = started.get("identity")
    return identity if isinstance(identity, dict) else dict(data.manifest)


def _instruments(data: RunData, notes: list[str]) -> dict[str, InstrumentRecord]:
    planned = ((data.plan.get("station") or {}).get("instruments")) or {}
    identified = identified_instruments(data.events)     # the journal's, not the manifest's
    run_date = str(_recorded_identity(data).get("started_at") or "")[:10]
    out = {}
    uut = data.plan.get("unit_under_test") or {}
    for role in sorted(set(planned) | set(identified)):
        identity = (planned.get(role) or {}).get("identity") or {}
        if role == "gyro" and not identity:
            # The gyro is the unit under test: its identity is the procedure's, and it
            # has no calibration due date of its own (this run is its calibration).
            identity = {"make": "unit under test", "model": uut.get("model"),
                        "serial": uut.get("serial"), "calibration_due": None}
        due = identity.get("calibration_due")
        overdue = bool(due and run_date and str(due) < run_date)
        if overdue:
            notes.append(f"{role}: calibration was due {due}, before the run ({run_date})")
        out[role] = InstrumentRecord(
            (identified.get(role) or planned.get(role) or {}).get("driver"),
            (identified.get(role) or {}).get("address"),
            (identified.get(role) or {}).get("description"),
            identity.get("make"), identity.get("model"), identity.get("serial"), due, overdue,
            identity.get("calibration_waiver"), identity.get("calibration_certificate"),
            identity.get("calibrated_by"))
    return out


def compute_results(data: RunData, notes: list[str]) -> Results:
    """Every figure of results.json from reduced run data (see the module docstring), judged.

    One builder per section, in the order the keys appear in the file; each
    appends what it could not compute to ``notes``. The limits and the physics
    checks are judged on the measured sections, then the verdicts join them.
    """
    measured = _measure(data, notes)
    view = measured.to_json()
    acceptance = tuple(evaluate_acceptance(view, data.plan.get("acceptance") or [], notes,
                                           measured=measured_needs(data)))
    sf_tolerance = (data.plan.get("sanity") or {}).get("sf_tolerance_pct")
    found = instrument_findings(view["instruments"])
    verdict = overall_verdict(check_physics(view, sf_tolerance), acceptance, found.blockers)
    return replace(measured, provenance=measured.provenance.judged(found.checks),
                   acceptance=acceptance, verdict=verdict, notes=tuple(notes))


def _measure(data: RunData, notes: list[str]) -> Results:
    """The sections and their uncertainty budgets, not yet judged against the limits."""
    uut = data.plan.get("unit_under_test") or {}
    nominal_sf = float(uut.get("nominal_scale_factor") or 1.0)
    sweep = _sweep_sections(data, notes)
    earth_dph = _earth_rate_dph(data.plan, notes)
    bias = _bias_sections(data, [e.result for e in sweep.entries], nominal_sf, earth_dph, notes)
    allan = _allan(data, nominal_sf, notes)
    compensation = _compensation(sweep, bias, notes)
    sections = _other_sections(data, nominal_sf, notes)
    provenance = _provenance(data, _instruments(data, notes))
    budget = uncertainty_budget(sweep, bias, compensation, allan,
                                [_mean_u(s) for s in data.steps if s.step.kind in _BUDGETED],
                                data.plan.get("station") or {}, nominal_sf, notes)
    return Results(
        UnitUnderTest(uut.get("model"), uut.get("serial"), uut.get("output_units"), nominal_sf),
        sweep, bias, allan, compensation, sections, earth_dph, REFERENCE_TEMP_C, provenance,
        DEFINITIONS, budget, sections.stated_uncertainties())


#: The step kinds whose means enter the sweep and bias budgets (the others have their own).
_BUDGETED = frozenset(StepKind) - {StepKind.THRESHOLD, StepKind.RATE_LIMIT,
                                   StepKind.FREQUENCY_RESPONSE, StepKind.MAGNETIC,
                                   StepKind.TILT, StepKind.TURN_ON, StepKind.TURN_ON_CYCLE}


def _other_sections(data: RunData, nominal_sf: float, notes: list[str]) -> TestSections:
    """imu … turn_on_repeatability, each built by its own module, in file order."""
    return TestSections(
        _imu(data, notes),
        interference_section(data.folder.path, data.record, data.events, nominal_sf, notes),
        magnetic_section(data.steps, data.plan, data.events, nominal_sf, notes),
        tilt_section(data.folder.path, data.record, data.events, data.record.gravity_g, notes),
        _threshold(data, nominal_sf, notes),
        _rate_limits(data, notes),
        _frequency_response(data, nominal_sf, notes),
        _turn_on(data, nominal_sf, notes),
        _repeatability(data, nominal_sf, notes))


def measured_needs(data: RunData) -> frozenset[Need]:
    """What the completed steps measured, in the terms of the catalogue's :class:`Need`.

    An acceptance limit whose metric needs more is NOT EVALUATED: a report
    rebuilt on an interrupted run must not grade the noise terms on a short
    static because the long Allan hold never ran. ``allan`` holds only when the
    plan's longest Allan hold completed and is the record the fit used.
    """
    done = [s.step for s in data.steps]
    sweep_temps = {s.setpoint_c for s in done if s.kind == StepKind.DWELL}
    hold_temps = {s.setpoint_c for s in done if s.kind in (StepKind.STATIC, StepKind.ALLAN)}
    needs = set()
    if sweep_temps:
        needs.add(Need.SWEEP)
    if len(sweep_temps) >= 2:
        needs.add(Need.SWEEP_TEMPS)
    if len(hold_temps) >= 2:
        needs.add(Need.BIAS_TEMPS)
    planned = [s for s in data.record.steps if s.kind == StepKind.ALLAN
               and (s.mounting is None or s.mounting in _unit_under_test_mountings(data.record))]
    longest = max(planned, key=lambda s: s.duration_s, default=None)
    if (longest is not None and data.allan_step is not None
            and data.allan_step.step.step_id == longest.step_id):
        needs.add(Need.ALLAN)
    needs.update(need for kind, need in _KIND_NEEDS if _all_done(data, kind))
    needs.update(Need.rate_limit(sign) for sign in (1.0, -1.0)
                 if _all_done(data, StepKind.RATE_LIMIT, sign))
    return frozenset(needs)


#: step kinds whose every planned step completing measures a need
_KIND_NEEDS = ((StepKind.THRESHOLD, Need.THRESHOLD),
               (StepKind.FREQUENCY_RESPONSE, Need.FREQUENCY_RESPONSE),
               (StepKind.TURN_ON, Need.TURN_ON),
               (StepKind.TURN_ON_CYCLE, Need.TURN_ON_REPEATABILITY))


def _all_done(data: RunData, kind: StepKind, sign: float | None = None) -> bool:
    """Every planned step of ``kind`` (of the unit's own axis; one ``sign`` of rate when given)
    completed: a threshold or a rate walk cut short is not judged on its first part."""
    own = _unit_under_test_mountings(data.record)
    planned = {s.step_id for s in data.record.steps if s.kind == kind
               and (s.mounting is None or s.mounting in own)
               and (sign is None or s.rate_dps * sign > 0)}
    return bool(planned) and planned <= {s.step.step_id for s in data.steps}


def _threshold(data: RunData, nominal_sf: float, notes: list[str]) -> ThresholdResults | None:
    """Threshold and resolution from the threshold dwells, in plan order (analysis/rate/threshold.py)."""
    order = {s.step_id: i for i, s in enumerate(data.record.steps)}
    dwells = [ThresholdDwell(s.step.step_id, s.step.setpoint_c, float(s.step.base_rate_dps or 0.0),
                             s.step.rate_dps, s.output_mean, s.output_sem,
                             float(s.step.confidence or 0.95),
                             float(s.step.max_error_fraction or 0.5))
              for s in sorted(data.steps, key=lambda s: order[s.step.step_id])
              if s.step.kind == StepKind.THRESHOLD]
    return threshold_section(dwells, nominal_sf, notes)


def _frequency_response(data: RunData, nominal_sf: float, notes: list[str]
                        ) -> frequency_section.FrequencyResults | None:
    """Gain, phase, −3 dB bandwidth from the frequency steps' samples (reports/sections/frequency.py)."""
    order = {s.step_id: i for i, s in enumerate(data.record.steps)}
    dwells = []
    for s in sorted(data.steps, key=lambda s: order[s.step.step_id]):
        step = s.step
        if step.kind != StepKind.FREQUENCY_RESPONSE or step.freq_hz is None:
            continue
        columns = _good_columns(data, step.step_id, ("t_s", "gyro", "table_rate_dps"))
        dwells.append(frequency_section.FrequencyDwell(
            step.step_id, step.setpoint_c, float(step.freq_hz), float(step.amplitude_dps or 0.0),
            float(step.phase_at_hz or step.freq_hz), columns["t_s"], columns["gyro"],
            columns["table_rate_dps"]))
    return frequency_section.frequency_section(dwells, nominal_sf, data.record.sample_rate_hz,
                                               notes)


def _turn_on(data: RunData, nominal_sf: float, notes: list[str]) -> TurnOnResults | None:
    """Turn-on time and warm-up from the turn_on steps' power cycles and samples
    (reports/sections/turn_on.py); a step's last power cycle is the one its data follows."""
    done = completed_attempts(data.events)
    cycles = {e["step_id"]: e for e in data.events
              if e.get("event") == JournalEvent.UNIT_POWER_CYCLE}
    records = []
    for step in data.record.steps:
        if step.kind != StepKind.TURN_ON or step.step_id not in done:
            continue
        cycle = cycles.get(step.step_id)
        if cycle is None:
            notes.append(f"turn_on {step.step_id}: the journal has no power cycle; not reduced")
            continue
        columns = _good_columns(data, step.step_id, ("t_s", "gyro"))
        records.append(TurnOnRecord(
            step.step_id, step.setpoint_c, float(step.band_dph or 0.0),
            float(cycle["on_clock_s"]), float(cycle["first_frame_after_s"]),
            float(cycle["poll_s"]), columns["t_s"], columns["gyro"] / nominal_sf * 3600.0))
    return turn_on_section(records, notes)


def _repeatability(data: RunData, nominal_sf: float, notes: list[str]
                   ) -> RepeatabilityResults | None:
    """Turn-on-to-turn-on repeatability from the turn_on_cycle steps' samples."""
    done = completed_attempts(data.events)
    cycles = []
    for step in data.record.steps:
        if step.kind == StepKind.TURN_ON_CYCLE and step.step_id in done:
            columns = _good_columns(data, step.step_id, ("t_s", "gyro"))
            cycles.append(CycleRecord(step.step_id, step.setpoint_c, columns["t_s"],
                                      columns["gyro"] / nominal_sf * 3600.0))
    return repeatability_section(cycles, notes)


def _rate_limits(data: RunData, notes: list[str]) -> rate_limits.RateLimitResults | None:
    """Maximum input rate each way from the rate-limit walk (analysis/rate/rate_limits.py)."""
    dwells = [rate_limits.LimitDwell(s.step.step_id, s.step.setpoint_c, s.step.rate_dps,
                                     s.output_mean, float(s.step.linearity_tolerance_pct or 1.0),
                                     int(s.step.fit_rates or 3))
              for s in data.steps if s.step.kind == StepKind.RATE_LIMIT]
    return rate_limits.rate_limits_section(dwells, notes)


def _mean_u(s: StepSummary) -> StepMean:
    return StepMean(s.step.kind.value, MeanU(s.step.setpoint_c, s.step.rate_dps, s.output_mean,
                                             s.output_sem, s.sem_dof, s.step.step_id))


#: How the single numbers of results.json are chosen when several temperatures exist.
DEFINITIONS = {
    "scale_factor_ls": f"LS line at the temperature closest to {REFERENCE_TEMP_C:g} °C",
    "nonlinearity": "worst over temperatures",
    "asymmetry_ppm": "largest magnitude over temperatures, sign kept",
    "bias": "static holds: mean/SF(T)·3600 − Earth rate (vertical axis, station latitude)",
    "allan": "longest static/allan hold, ÷ nominal scale factor, deg/h",
    "threshold": "threshold_dps: smallest increment at zero rate resolved at the stated "
                 "confidence and within the stated fraction, every larger one too (worst over "
                 "temperatures); resolution_dps: the same at the non-zero bases (worst)",
    "frequency_response": "bandwidth_hz: first −3 dB crossing of the gain (output amplitude over "
                          "nominal SF × table rate amplitude), smallest over temperatures; "
                          "phase_deg: output against table rate at the stated frequency (first "
                          "temperature)",
    "turn_on": "time_to_first_data_s: output-on command to the first valid frame; warmup_tau_s "
               "/ warmup_amplitude_dph: fit of b∞ + A·e^(−t/τ) from the output-on; "
               "time_to_band_s: until the fitted bias stays within ±band_dph of b∞ (first "
               "turn_on step)",
    "turn_on_repeatability": "std_dph: standard deviation of the cycles' mean biases (each "
                             "logged after the settling time), u = s/√(2(N−1)); in_run_std_dph: "
                             "pooled standard deviation of 1-s means within the cycles",
    "rate_limits": "max_positive_dps / max_negative_dps: the largest walked rate that, with every "
                   "smaller one, stays within the stated % of the linear fit (smallest over "
                   "temperatures)",
}


def _sweep_sections(data: RunData, notes: list[str]) -> SweepResults:
    """scale_factor, scale_factor_ls, nonlinearity, asymmetry_ppm, sf_temperature."""
    entries = _scale_factor(data, notes)
    if not entries:
        notes.append("no ± rate sweep completed: scale factor, nonlinearity and asymmetry are null")
    sf_temperature = None
    if len(entries) >= 2:
        sf_temperature = bias_mod.sf_temperature([e.result for e in entries], REFERENCE_TEMP_C)
    elif entries:
        notes.append("sf_temperature: sweeps at one temperature only; needs two or more")
    return SweepResults(tuple(entries), REFERENCE_TEMP_C, sf_temperature)


def _bias_sections(data: RunData, sf_results: list[ScaleFactorResult], nominal_sf: float,
                   earth_dph: float, notes: list[str]) -> BiasResults:
    """bias (per temperature) and bias_temperature."""
    points = _bias(data, sf_results, nominal_sf, earth_dph, notes)
    sensitivity = None
    if len(points) >= 2:
        sensitivity = bias_mod.bias_sensitivity_dph_per_c(
            [bias_mod.BiasPoint(p.temp_c, p.bias_dph) for p in points])
    else:
        notes.append(f"bias_temperature: bias at {len(points)} temperature(s); needs two or more")
    return BiasResults(tuple(points), sensitivity)


def _compensation(sweep: SweepResults, bias: BiasResults,
                  notes: list[str]) -> CompensationResults:
    bias_pairs = [(p.temp_c, p.bias_dph) for p in bias.entries]
    sf_pairs = [(e.temp_c, e.result.sf) for e in sweep.entries]
    return CompensationResults(tuple(bias_pairs), tuple(sf_pairs),
                               {"bias_dph": _comp_tables(bias_pairs, "bias", notes),
                                "sf": _comp_tables(sf_pairs, "scale factor", notes)})


def _run_info(data: RunData) -> RunInfo:
    """results.json ``run``: who, when and how, as run_started fixed them (signed), never the
    mutable manifest's copy; the state and times from the journal."""
    manifest = data.manifest
    identity = _recorded_identity(data)
    recorded = {key: identity.get(key, manifest.get(key)) for key in IDENTITY_KEYS}
    started = next((e for e in data.events if e.get("event") == JournalEvent.RUN_STARTED), {})
    completed = [e for e in data.events if e.get("event") == JournalEvent.RUN_COMPLETED]
    # The report of a run is built when its last step is done, before the run closes (the
    # report's hash goes into the closing line), so ended_at is not known yet: the time the
    # steps were done is, and it is what a certificate's "date of calibration" means.
    done = [e for e in data.events if e.get("event") == JournalEvent.STEPS_DONE and e.get("wall_time")]
    # ... and the calibration began with its first step, not with connecting the instruments
    first = next((e for e in data.events if e.get("event") == JournalEvent.STEP_STARTED
                  and e.get("wall_time")), None)
    return RunInfo(
        recorded, run_mode(recorded["mode"]),
        plan_sha256=started.get("plan_sha256", manifest.get("plan_sha256")),
        ended_at=completed[-1].get("ended_at") if completed else None,
        state="done" if completed else str(manifest.get("state") or "running"),
        steps_done_at=_utc_text(done[-1]["wall_time"]) if done else None,
        steps_started_at=_utc_text(first["wall_time"]) if first else None,
        # the procedure's own length (the plan's ETA): on simulated time not the wall span
        procedure_s=manifest.get("eta_s"))


def _utc_text(wall_time: float | str) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S+0000", time.gmtime(float(wall_time)))


def _provenance(data: RunData, instruments: dict[str, InstrumentRecord]) -> Provenance:
    """Who, what, where and with what: run, procedure, station, instruments, inputs, journal."""
    plan, manifest = data.plan, data.manifest
    station = plan.get("station") or {}
    return Provenance(
        _run_info(data), plan.get("procedure"),
        StationRecord(station.get("name"), station.get("file"), station.get("site")),
        instruments,
        {role: InputRecord(e.get("copy"), e.get("source"), e.get("sha256"))
         for role, e in (manifest.get("inputs") or {}).items()},
        _journal_summary(data.events),
        tuple(StepRecord(s.step.step_id, s.step.kind.value, s.step.setpoint_c, s.step.rate_dps,
                         s.output_mean, s.n_used, s.n_logged, s.trimmed_to_revolutions,
                         s.sensor_temp_c, s.drift) for s in data.steps))


# -- writing ------------------------------------------------------------------------------

def build_report(run_dir: str | Path, journal: Journal | None = None,
                 signer: Signer | None = None) -> dict[str, Any]:
    """Compute, write report/results.json and report/report.html, journal their SHA-256.

    ``journal``: the engine's open journal when called at the end of a run
    (a second writer would fork the hash chain; the run seals it when it
    exits); None opens one, and seals it with ``signer`` when given, so a
    rebuilt report is as authenticated as the run. With ``signer`` the report
    itself carries a signature over the chain head and its own numbers.
    """
    if journal is not None:
        return _build(Path(run_dir), journal, signer)
    folder = RunFolder.open(Path(run_dir))
    with Journal(folder.path / "journal.jsonl") as own:
        # What a rebuild cut short left behind (a temporary file, a report file never
        # recorded) is set aside and named before anything is written.
        set_aside(folder.path, own, folder.journal_events(), folder.read_manifest())
        results = _build(folder.path, own, signer)
        if signer is not None:
            signer.seal(own, str(results.get("run", {}).get("run_id") or ""),
                        reason="report rebuilt")
    return results


def _build(run_dir: Path, journal: Journal, signer: Signer | None) -> dict[str, Any]:
    notes: list[str] = []
    data = read_run(run_dir, notes)
    results = replace(compute_results(data, notes),
                      built_at=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
    return _write_report(data, results, journal, signer)


def _write_report(data: RunData, results: Results, journal: Journal,
                  signer: Signer | None) -> dict[str, Any]:
    """Sign (when a signer is given), write results.json and report.html; the file's object."""
    started = next((e for e in data.events if e.get("event") == JournalEvent.RUN_STARTED), {})
    if signer is not None:
        unsigned = sha256_bytes(results_bytes(results.to_json()))
        signature = {"signed": True, **signer.sign_report(
            str(data.manifest.get("run_id", "")), journal.last_sha256, unsigned)}
    else:
        signature = {"signed": False, "key_fingerprint": started.get("signing_key")}
    final = finite_or_none(replace(results, signature=signature).to_json())
    encoded = results_bytes(final)
    html = render_html(final).encode()
    root = data.folder.path
    write_bytes_atomic(root / RESULTS_FILE, encoded)
    write_bytes_atomic(root / HTML_FILE, html)
    journal.append(JournalEvent.REPORT_WRITTEN, files={RESULTS_FILE: sha256_bytes(encoded),
                                            HTML_FILE: sha256_bytes(html)})
    return final
