"""Property: whatever an operator's editor does to a valid procedure, validation either
accepts it (and it expands to a plan) or explains it with located problems — never a crash."""

import copy
import math
import tempfile
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from gyrocal.orchestrator.plan import expand_plan, format_plan
from gyrocal.orchestrator.procedure import load_procedure
from gyrocal.problems import ProcedureError

pytestmark = pytest.mark.timeout(120)

REPO = Path(__file__).resolve().parents[2]
SIM = str(REPO / "stations" / "sim.yaml")
EXAMPLES = {}
for _path in sorted((REPO / "procedures").glob("*.yaml")):
    _data = yaml.safe_load(_path.read_text(encoding="utf-8"))
    _data["station"] = SIM             # absolute, so the mutated copy can live anywhere
    EXAMPLES[_path.name] = _data

WORKDIR = tempfile.TemporaryDirectory(prefix="gyrocal-property-")

# values an editor (or a tired operator) might leave behind
junk = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([0, -1, -40, 10**400, 2**63]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["", "20", "20 min", "-5 s", "1e309 h", "90 deg/s", "25 °C", "fast", "sim",
                     "nonlinearity.rms_pct", "sf_sweep", "static", "allan", "log", "both",
                     "2027-13-45", "../../etc/passwd"]),
    st.text(max_size=12),
    st.lists(st.integers(min_value=-1000, max_value=1000), max_size=4),
    st.dictionaries(st.text(max_size=6), st.integers(), max_size=3),
)


def paths_in(node, prefix=()):
    """Every (key path) in the tree, containers included."""
    found = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            found += paths_in(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            found += paths_in(value, (*prefix, index))
    return found


def resolve(data, path):
    node = data
    for part in path:
        node = node[part]
    return node


@st.composite
def mutated_procedures(draw):
    name = draw(st.sampled_from(sorted(EXAMPLES)))
    data = copy.deepcopy(EXAMPLES[name])
    touched_station = False
    for _ in range(draw(st.integers(min_value=1, max_value=4))):
        paths = paths_in(data)
        path = draw(st.sampled_from(paths))
        target = resolve(data, path)
        action = draw(st.sampled_from(["drop", "unknown_key", "replace", "truncate"]))
        touched_station |= bool(path) and path[0] == "station"
        if action == "drop" and path:
            parent = resolve(data, path[:-1])
            del parent[path[-1]]
        elif action == "unknown_key" and isinstance(target, dict):
            target[draw(st.text(min_size=1, max_size=8))] = draw(junk)
        elif action == "truncate" and isinstance(target, list):
            del target[draw(st.integers(min_value=0, max_value=len(target))):]
        elif path:
            resolve(data, path[:-1])[path[-1]] = draw(junk)
        else:
            data = draw(junk)
    return name, data, touched_station


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=mutated_procedures())
def test_validation_ends_in_a_plan_or_located_problems(case):
    name, data, touched_station = case
    path = Path(WORKDIR.name) / name
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False), encoding="utf-8")
    try:
        procedure = load_procedure(path)
    except ProcedureError as error:
        event(f"{len(error.problems) > 1 and 'several problems' or 'one problem'}")
        assert error.problems
        for problem in error.problems:
            assert problem.file and problem.message
            assert problem.line is None or problem.line >= 1
            str(problem)
        assert touched_station or any(p.file == str(path) for p in error.problems)
        assert all(p.file == str(path) for p in error.problems) or touched_station
        return
    event("valid after mutation")
    plan = expand_plan(procedure)
    assert plan.steps and math.isfinite(plan.total_s) and plan.total_s >= 0
    assert len({s.step_id for s in plan.steps}) == len(plan.steps)
    assert format_plan(plan)
