"""Exit 2 has one owner: every input error subclasses :class:`gyrocal.errors.BadInput`.

The command line maps that one base to exit 2. Before, it looked the input
errors up by module and name with ``__import__`` and skipped any it could not
find, so renaming one silently turned exit 2 into exit 3. Here the product's
``*Error`` classes are found on the source (outside the drivers, whose errors
are instrument faults), and each must either be bad input or be named below
with what becomes of it; then each kind of bad input goes through the real
command line.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, main
from gyrocal.errors import BadInput, RunFaultError

ROOT = Path(__file__).resolve().parents[1]
#: repository folder → installed package; instruments/ is left out: its errors are faults
FOLDERS = {"gyrocal": "gyrocal", "models": "gyrocal.models", "record": "gyrocal.record",
           "analysis": "gyrocal.analysis", "metrology": "gyrocal.metrology",
           "orchestrator": "gyrocal.orchestrator", "reports": "gyrocal.reports",
           "app": "gyrocal.app"}

#: Raised on bad input; each must reach the command line as exit 2.
INPUT_ERRORS = {
    "gyrocal.inputs.InputError",                      # procedure, station, model, IMU files
    "gyrocal.models.gyro_model.ModelError",           # a model that breaks the contract
    "gyrocal.analysis.log_contract.LogFormatError",   # a measured log
    "gyrocal.record.run_folder.RunFolderError",       # a folder that is no run
    "gyrocal.record.signing.SigningKeyError",         # an unusable key file
}

#: Not bad input by itself, and why: a fault (exit 3), or turned into bad input where caught.
OTHER_ERRORS = {
    "gyrocal.record.locks.LockBusyError": "another process holds the lock (exit 3)",
    "gyrocal.orchestrator.remount.MountCheckError": "raised again as a RunFaultError by the remount step",
    "gyrocal.units.UnitError": "collected into an InputError by the schema readers",
    "gyrocal.record.ledger.LedgerError": "reported by verify and ledger as a failed audit",
    "gyrocal.record.journal.JournalError": "reported by verify as a failed audit",
    "gyrocal.reports.runs.database.RunsDatabaseError": "raised again as BadInput by the runs commands",
    "gyrocal.models.table.TableLimitError": "the simulated table's refusal, answered as an ACUTROL error",
    "gyrocal.models.table.TableInterlockError": "the simulated table's refusal, answered as an ACUTROL error",
    "gyrocal.models.table.TableModeError": "the simulated table's refusal, answered as an ACUTROL error",
    "gyrocal.models.sim_state.SimStateError": "a dry run's saved state that does not fit: raised again as a RunFaultError naming the journal line",
}


def _error_classes() -> dict[str, type]:
    """Every top-level class named ``*Error`` in the product (outside the drivers)."""
    found: dict[str, type] = {}
    for folder, package in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            names = [node.name for node in tree.body
                     if isinstance(node, ast.ClassDef) and node.name.endswith("Error")]
            if not names:
                continue
            parts = [p for p in path.relative_to(ROOT / folder).with_suffix("").parts
                     if p != "__init__"]
            module = importlib.import_module(".".join([package, *parts]))
            for name in names:
                found[f"{module.__name__}.{name}"] = getattr(module, name)
    return found


ERRORS = _error_classes()


def test_the_scan_finds_the_known_errors() -> None:
    assert set(ERRORS) >= INPUT_ERRORS
    assert "gyrocal.errors.RunFaultError" in ERRORS


@pytest.mark.parametrize("name", sorted(INPUT_ERRORS))
def test_each_input_error_is_bad_input(name: str) -> None:
    assert issubclass(ERRORS[name], BadInput)
    assert not issubclass(ERRORS[name], RunFaultError)


def test_every_error_class_is_either_bad_input_or_accounted_for() -> None:
    """A new ``*Error`` class must be bad input, a run fault, or say here what becomes of it."""
    unplaced = sorted(name for name, cls in ERRORS.items()
                      if not issubclass(cls, (BadInput, RunFaultError))
                      and name not in OTHER_ERRORS)
    assert unplaced == [], ("subclass gyrocal.errors.BadInput (exit 2) or add to OTHER_ERRORS "
                            f"with what becomes of it: {unplaced}")
    misplaced = sorted(name for name in OTHER_ERRORS if name in ERRORS
                       and issubclass(ERRORS[name], BadInput))
    assert misplaced == []


def test_the_command_line_finds_no_exception_class_by_name() -> None:
    tree = ast.parse((ROOT / "gyrocal" / "cli.py").read_text(encoding="utf-8"))
    calls = [node.func.id for node in ast.walk(tree)
             if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)]
    assert "__import__" not in calls
    swallowed = [ast.unparse(node.type) for node in ast.walk(tree)
                 if isinstance(node, ast.ExceptHandler) and node.type is not None
                 and "ImportError" in ast.unparse(node.type)]
    assert swallowed == []


# -- each kind through the real command line -------------------------------------------------

def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _bad_procedure(tmp_path: Path) -> tuple[list[str], str]:
    path = _write(tmp_path, "p.yaml", "name: x\nbogus: 1\n")
    return ["validate", str(path)], "p.yaml:2: bogus: unknown key 'bogus'"


def _bad_model(tmp_path: Path) -> tuple[list[str], str]:
    path = _write(tmp_path, "m.yaml", "version: 1\nscale_factor: 1\neffects: {a: 1}\n")
    return (["discrepancy", "--model", str(path), "--measured", str(tmp_path / "nowhere"),
             "--out", str(tmp_path / "d")], "m.yaml:3: effects: must be a list")


def _bad_log(tmp_path: Path) -> tuple[list[str], str]:
    path = _write(tmp_path, "one.csv", "t_s,rate_dps\n0,1\n")
    return ["analyze", "allan", str(path)], "one.csv: fewer than 2 rows"


def _not_a_run(tmp_path: Path) -> tuple[list[str], str]:
    (tmp_path / "notrun").mkdir()
    return ["report", str(tmp_path / "notrun")], "notrun: not a run folder"


@pytest.mark.parametrize("case, error", [
    (_bad_procedure, "InputError"), (_bad_model, "ModelError"), (_bad_log, "LogFormatError"),
    (_not_a_run, "RunFolderError")])
def test_each_kind_of_bad_input_exits_2_naming_the_file(tmp_path: Path, capsys, case,
                                                       error: str) -> None:
    argv, expected = case(tmp_path)
    with pytest.raises(BadInput) as raised:       # the exception the command line maps
        main(["--debug", *argv])
    assert type(raised.value).__name__ == error
    capsys.readouterr()
    assert main(argv) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert expected in err
    assert "Traceback" not in err and "internal error" not in err
