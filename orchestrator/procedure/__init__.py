"""The procedure language: what to measure, at which temperatures and rates, what passes.

One package, one job per module: ``types`` (the typed procedure, frozen dataclasses and the
language's constants), ``parser`` (the file to those types, through the common loader
``gyrocal.inputs`` and schema reader ``gyrocal/schema.py``), ``kinds`` (one reader per
test kind), ``rates`` (rate lists and generated schedules), ``envelope`` (values against the
procedure's and the station's limits) and ``acceptance`` (the limits QA judges by).

The names other modules use are re-exported here.
"""

from __future__ import annotations

from gyrocal.orchestrator.procedure.parser import load_procedure
from gyrocal.orchestrator.procedure.rates import generate_rates
from gyrocal.orchestrator.procedure.types import (
    DEFAULT_FIT_RATES,
    DEFAULT_FR_CYCLES,
    DEFAULT_FR_SETTLE_CYCLES,
    DEFAULT_LINEARITY_TOLERANCE_PCT,
    DEFAULT_MAX_ETA_S,
    DEFAULT_THRESHOLD_CONFIDENCE,
    DEFAULT_THRESHOLD_ERROR_FRACTION,
    DIRECTIONS,
    MAX_DECLARED_DURATION_S,
    MAX_DURATION_S,
    MAX_LIST,
    MIN_ACCEL_DPS2,
    MIN_RAMP_C_PER_MIN,
    MIN_SAMPLES_PER_PERIOD,
    MOUNTING_ORDERS,
    OUTPUT_UNITS,
    PROCEDURE_VERSION,
    SPACINGS,
    TEST_KINDS,
    TILT_POINTS,
    AcceptanceLimit,
    AllanTest,
    ChamberSafety,
    DataQuality,
    Defaults,
    FrequencyResponseTest,
    MagneticTest,
    MountingSpec,
    Procedure,
    RateLimitTest,
    RateSchedule,
    Safety,
    SoakCriterion,
    StaticTest,
    SweepTest,
    TableInterferenceTest,
    TableSafety,
    TemperatureStep,
    Test,
    TestKind,
    ThresholdTest,
    TiltLinearityTest,
    TurnOnRepeatabilityTest,
    TurnOnTest,
    UnitUnderTest,
)
from gyrocal.problems import ProcedureError

__all__ = ["AcceptanceLimit", "AllanTest", "ChamberSafety", "DEFAULT_FIT_RATES", "DEFAULT_FR_CYCLES", "DEFAULT_FR_SETTLE_CYCLES", "DEFAULT_LINEARITY_TOLERANCE_PCT", "DEFAULT_MAX_ETA_S", "DEFAULT_THRESHOLD_CONFIDENCE", "DEFAULT_THRESHOLD_ERROR_FRACTION", "DIRECTIONS", "DataQuality", "Defaults", "FrequencyResponseTest", "MAX_DECLARED_DURATION_S", "MAX_DURATION_S", "MAX_LIST", "MIN_ACCEL_DPS2", "MIN_RAMP_C_PER_MIN", "MIN_SAMPLES_PER_PERIOD", "MOUNTING_ORDERS", "MagneticTest", "MountingSpec", "OUTPUT_UNITS", "PROCEDURE_VERSION", "Procedure", "ProcedureError", "RateLimitTest", "RateSchedule", "SPACINGS", "Safety", "SoakCriterion", "StaticTest", "SweepTest", "TEST_KINDS", "TILT_POINTS", "TableInterferenceTest", "TableSafety", "TemperatureStep", "Test", "TestKind", "ThresholdTest", "TiltLinearityTest", "TurnOnRepeatabilityTest", "TurnOnTest", "UnitUnderTest", "generate_rates", "load_procedure"]
