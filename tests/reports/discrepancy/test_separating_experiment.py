"""The separating experiment is a procedure fragment the orchestrator can really run."""

from pathlib import Path

import pytest
import yaml

from gyrocal.analysis.discrepancy.lookalikes import separating_experiment
from gyrocal.orchestrator.plan import expand_plan
from gyrocal.orchestrator.procedure import load_procedure

REPO = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(
    "best, rivals, kwargs",
    [
        ("thermal_lag", ["temp_rate_bias"], {"tau_s": 600.0}),
        ("sf_asymmetry", ["sf_nonlinearity_quadratic"], {"rate_levels_dps": (10.0, 50.0, 100.0)}),
        ("warmup_transient", ["bias_ramp"], {"tau_s": 1200.0}),
        ("table_angle_harmonic", ["periodic_interference"], {}),
    ],
)
def test_fragment_appended_to_a_procedure_validates_and_expands(tmp_path, best, rivals, kwargs):
    fragment = yaml.safe_load(separating_experiment(best, rivals, **kwargs))
    procedure = yaml.safe_load((REPO / "procedures" / "smoke.yaml").read_text())
    procedure["station"] = str(REPO / "stations" / "sim.yaml")
    procedure["safety"]["chamber"].update(min_temp_c=0.0, max_temp_c=50.0)
    procedure["sequence"] = fragment["sequence"]
    procedure["acceptance"] = []
    path = tmp_path / "separating.yaml"
    path.write_text(yaml.safe_dump(procedure, sort_keys=False))
    plan = expand_plan(load_procedure(path))
    assert len(plan.steps) >= 3 and plan.total_s > 0


def test_no_rival_no_experiment():
    assert separating_experiment("sf_asymmetry", []) == ""
