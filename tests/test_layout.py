"""How the package is assembled, and the layer stack its folders promise, checked on the source.

The layers form a strict stack, bottom up; a module may import its own layer and
the layers below it, never above, and no layer list carries an exception:

====  ==============  ===========================================================
 0    base            ``gyrocal/`` leaves: errors and exit codes, the input
                      languages' common loader, schema, problems and units
 1    models          the physics and the effect catalogue
 2    instruments     drivers, the driver registry, simulators
 3    record          the run folder, the journal, plan/manifest readers,
                      samples, signing, ledger, locks
 4    analysis        numbers from samples: Allan, rate tests, thermal, IMU,
                      environment, measured logs, discrepancy
 5    metrology       GUM, uncertainty budgets, the metric catalogue, decisions
 6    orchestrator    procedures, stations, plans, the engine, the safe state
 6    reports         typed results, report build, HTML, certificate, verify
 7    app             the commands and the live page
 8    cli             argument parsing only
====  ==============  ===========================================================

``orchestrator`` and ``reports`` share a level and import nothing of each other:
a run is executed without the report code, a report is built from the run
record alone. The import graph is read from the source with ``ast`` (every
import, including those inside functions), so a lazy import cannot hide a breach.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: repository folder → installed package (pyproject.toml's package-dir mapping)
PACKAGES = {"gyrocal": "gyrocal", "models": "gyrocal.models",
            "instruments": "gyrocal.instruments", "record": "gyrocal.record",
            "analysis": "gyrocal.analysis", "metrology": "gyrocal.metrology",
            "orchestrator": "gyrocal.orchestrator", "reports": "gyrocal.reports",
            "app": "gyrocal.app"}
#: the stack, bottom up: a layer may import the layers at lower levels (and its own)
LEVEL = {"base": 0, "models": 1, "instruments": 2, "record": 3, "analysis": 4,
         "metrology": 5, "orchestrator": 6, "reports": 6, "app": 7, "cli": 8}


def _may_import(layer: str, target: str) -> bool:
    return layer == target or LEVEL[target] < LEVEL[layer]


def _modules() -> dict[str, Path]:
    found = {}
    for folder, package in PACKAGES.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = [p for p in path.relative_to(ROOT / folder).with_suffix("").parts
                     if p != "__init__"]
            found[".".join([package, *parts])] = path
    return found


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names if a.name.startswith("gyrocal"))
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("gyrocal"):
            names.add(node.module)
    return names


def _layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in ("cli", "__main__"):
        return "cli"
    if len(parts) == 1 or parts[1] not in PACKAGES:
        return "base"  # the package root's leaves: version, errors, inputs, schema, units
    return parts[1]


GRAPH = {module: _imports(path) for module, path in _modules().items()}


@pytest.mark.parametrize("name", sorted(PACKAGES.values()))
def test_product_folders_install_under_the_gyrocal_namespace(name):
    module = importlib.import_module(name)
    assert module.__name__ == name


def _breaches(graph: dict[str, set[str]]) -> list[str]:
    return sorted(f"{module} imports {target}" for module, targets in graph.items()
                  for target in targets if not _may_import(_layer(module), _layer(target)))


def test_every_import_respects_the_stack():
    assert _breaches(GRAPH) == []


def test_every_product_folder_has_its_level():
    """A new top-level folder must be placed in the stack before anything may import it."""
    assert {_layer(m) for m in GRAPH} <= set(LEVEL)


def test_nothing_imports_the_command_line():
    users = sorted(m for m, ts in GRAPH.items() if "gyrocal.cli" in ts
                   and m not in ("gyrocal.__main__",))
    assert users == []


def test_functions_are_not_imported_inside_functions():
    """Imports sit at the top of a module, where the layer check and a reader see them.
    An import inside a function is allowed only with a ``# lazy: <measured reason>``
    comment on its line (e.g. a start-up cost measured for ``gyrocal --help``)."""
    found = []
    for module, path in _modules().items():
        lines = path.read_text(encoding="utf-8").splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for inner in ast.walk(node):
                if isinstance(inner, ast.Import | ast.ImportFrom) and \
                        "# lazy:" not in lines[inner.lineno - 1]:
                    found.append(f"{module}:{inner.lineno}")
    assert found == [], f"{len(found)} function-level imports without '# lazy:': {found[:20]}"


def test_no_import_cycles_between_modules():
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's strongly connected components
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in GRAPH.get(node, ()):
            if target not in GRAPH:
                continue
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in GRAPH:
        if module not in index:
            visit(module)
    assert cycles == []


def test_the_contract_sees_a_breach():
    """The checks above are not vacuous: an upward import and a sideways one are reported."""
    fake = {"gyrocal.instruments.fake": {"gyrocal.app.run_commands", "gyrocal.models.gyro_model"},
            "gyrocal.reports.fake": {"gyrocal.orchestrator.engine", "gyrocal.record.journal"},
            "gyrocal.analysis.fake": {"gyrocal.metrology.gum"}}
    assert _breaches(fake) == [
        "gyrocal.analysis.fake imports gyrocal.metrology.gum",
        "gyrocal.instruments.fake imports gyrocal.app.run_commands",
        "gyrocal.reports.fake imports gyrocal.orchestrator.engine",
    ]


def test_no_product_module_sets_the_plotting_backend():
    """Plots draw on ``matplotlib.figure.Figure`` (the Agg canvas, as ``reports/plots.py``),
    never through pyplot's global state: importing or running gyrocal does not change the
    backend of the process it runs in (``MPLBACKEND`` stays the user's)."""
    found = []
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and ast.unparse(node.func) == "matplotlib.use":
                found.append(f"{module}: matplotlib.use")
            elif isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if any(n == "matplotlib.pyplot" or n == "pyplot" for n in names):
                    found.append(f"{module}: imports pyplot")
    assert found == []


#: Product modules that may import pyarrow outside the run record (``record/``:
#: ``samples.py`` reads run chunks, ``run_folder.py`` writes them). Each reads or writes a
#: measured log a lab brings or gyrocal hands out, never a run's chunks:
PYARROW_OUTSIDE_THE_RECORD = {
    "gyrocal.analysis.measured_log": "reads an external measured log (CSV/Parquet)",
    "gyrocal.analysis.allan.sources": "streams external logs for `analyze allan`",
    "gyrocal.analysis.log_contract": "checks an external Parquet log's column types",
    "gyrocal.app.decode_capture": "writes the measured log decoded from a capture",
}


def _pyarrow_importers() -> set[str]:
    found = set()
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n == "pyarrow" or n.startswith("pyarrow.") for n in names):
                found.add(module)
    return found


def test_only_the_run_record_reads_run_chunks_with_pyarrow():
    """Issue 27: run chunks are read in one place (``record/samples.py``: the counted attempt,
    flagged samples left out); no other product module imports pyarrow but the external-log
    readers and writers named above."""
    importers = _pyarrow_importers()
    outside = sorted(m for m in importers if not m.startswith("gyrocal.record.")
                     and m not in PYARROW_OUTSIDE_THE_RECORD)
    assert outside == []
    # not vacuous: the reader and the writer are found, and every exception still needs one
    assert {"gyrocal.record.samples", "gyrocal.record.run_folder"} <= importers
    assert sorted(set(PYARROW_OUTSIDE_THE_RECORD) - importers) == []
