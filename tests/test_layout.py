"""How the package is assembled, and the layering its folders promise, checked on the source.

Layers, bottom up: the package root's leaves (``gyrocal.errors``: exit codes;
``gyrocal.inputs``: the one input-file loader; the version — they import nothing
of ours but each other) ·
``models`` (the shared physics) · ``instruments`` (drivers and simulators) ·
``orchestrator`` and ``reports`` · ``gyrocal.cli`` (the command line, which
only routes). A module may import its own layer and the layers below it.
The import graph is read from the source with ``ast`` (every import,
including those inside functions), so a lazy import cannot hide a breach.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: repository folder → installed package (pyproject.toml's package-dir mapping)
PACKAGES = {"gyrocal": "gyrocal", "models": "gyrocal.models",
            "instruments": "gyrocal.instruments", "orchestrator": "gyrocal.orchestrator",
            "reports": "gyrocal.reports"}
#: what each layer may import of ours (besides itself)
ALLOWED = {
    "base": set(),
    "models": {"base"},
    "instruments": {"base", "models"},
    "orchestrator": {"base", "models", "instruments", "reports"},
    "reports": {"base", "models", "orchestrator"},
    "cli": {"base", "models", "instruments", "orchestrator", "reports"},
}


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
        return "base"  # the package root's leaves: version, errors.py, inputs.py
    return parts[1]


GRAPH = {module: _imports(path) for module, path in _modules().items()}


@pytest.mark.parametrize(
    "name", ["gyrocal.models", "gyrocal.instruments", "gyrocal.orchestrator", "gyrocal.reports"]
)
def test_product_folders_install_under_the_gyrocal_namespace(name):
    module = importlib.import_module(name)
    assert module.__name__ == name


def test_every_import_respects_the_layers():
    breaches = sorted(
        f"{module} imports {target}"
        for module, targets in GRAPH.items() for target in targets
        if _layer(target) != _layer(module) and _layer(target) not in ALLOWED[_layer(module)]
    )
    assert breaches == []


def test_models_import_nothing_but_models_and_the_base():
    outside = sorted(f"{m} imports {t}" for m, ts in GRAPH.items() if _layer(m) == "models"
                     for t in ts if _layer(t) not in ("models", "base"))
    assert outside == []


def test_instruments_never_import_the_orchestrator_or_reports():
    upward = sorted(f"{m} imports {t}" for m, ts in GRAPH.items() if _layer(m) == "instruments"
                    for t in ts if _layer(t) in ("orchestrator", "reports", "cli"))
    assert upward == []


def test_nothing_imports_the_command_line():
    users = sorted(m for m, ts in GRAPH.items() if "gyrocal.cli" in ts
                   and m not in ("gyrocal.__main__",))
    assert users == []


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
    """The checks above are not vacuous: a made-up upward import is reported."""
    fake = {"gyrocal.instruments.fake": {"gyrocal.orchestrator.commands"}}
    breaches = [t for m, ts in fake.items() for t in ts
                if _layer(t) not in ALLOWED[_layer(m)] and _layer(t) != _layer(m)]
    assert breaches == ["gyrocal.orchestrator.commands"]


#: what reports/ may use of the orchestrator besides the run record: the audit trail's
#: signatures and ledger, the folder lock, and the signer a rebuilt report is sealed with
REPORTS_MAY_USE = ("gyrocal.orchestrator.record", "gyrocal.orchestrator.signing",
                   "gyrocal.orchestrator.ledger", "gyrocal.orchestrator.locks",
                   "gyrocal.orchestrator.commands")


def test_reports_read_runs_only_through_the_run_record():
    """Issue 15: one owner for the run record; the report and discrepancy read nothing else."""
    breaches = sorted(
        f"{module} imports {target}"
        for module, targets in GRAPH.items() if module.startswith("gyrocal.reports")
        for target in targets
        if target.startswith("gyrocal.orchestrator")
        and not any(target == ok or target.startswith(ok + ".") for ok in REPORTS_MAY_USE))
    assert not breaches, "\n".join(breaches)
    record_users = [m for m, t in GRAPH.items() if m.startswith("gyrocal.reports")
                    and any(x.startswith("gyrocal.orchestrator.record") for x in t)]
    assert "gyrocal.reports.build" in record_users and "gyrocal.reports.verify" in record_users


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
