"""Fixtures shared by every test folder."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
    """One dry run of procedures/smoke.yaml for the whole session (tests copy it to tamper)."""
    from pathlib import Path

    from gyrocal.cli import main

    root = Path(__file__).resolve().parents[1]
    run_dir = tmp_path_factory.getbasetemp() / "smoke-run"
    code = main(["run", str(root / "procedures" / "smoke.yaml"), "--sim", "--seed", "3",
                 "--out", str(run_dir), "--operator", "qa-test"])
    assert code == 0
    return run_dir
