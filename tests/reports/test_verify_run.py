"""gyrocal verify on copies of a real run folder: clean → 0, each kind of tampering → 1 naming it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from gyrocal.cli import main

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def run_copy(smoke_run, tmp_path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(smoke_run, copy)
    return copy


def _flip_last_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[-2] ^= 0x01
    path.write_bytes(bytes(data))


def test_untouched_run_verifies(run_copy, capsys):
    assert main(["verify", str(run_copy)]) == 0
    out = capsys.readouterr().out
    assert "OK" in out and "14 sample chunks" in out and "2 report files" in out


def _first_chunk(run: Path) -> Path:
    return sorted((run / "samples").rglob("*.parquet"))[0]


@pytest.mark.parametrize("target", [
    "chunk", "input", "plan", "results", "html", "journal",
])
def test_each_tampered_file_is_named(run_copy, capsys, target):
    paths = {
        "chunk": _first_chunk(run_copy),
        "input": run_copy / "inputs" / "procedure.yaml",
        "plan": run_copy / "plan.json",
        "results": run_copy / "report" / "results.json",
        "html": run_copy / "report" / "report.html",
        "journal": run_copy / "journal.jsonl",
    }
    path = paths[target]
    if target == "journal":
        lines = path.read_bytes().splitlines(keepends=True)
        event = json.loads(lines[10])
        event["wall_time"] += 1.0  # an edited history line; the next line's chain breaks
        lines[10] = json.dumps(event, sort_keys=True, separators=(",", ":")).encode() + b"\n"
        path.write_bytes(b"".join(lines))
    else:
        _flip_last_byte(path)
    assert main(["verify", str(run_copy)]) == 1
    err = capsys.readouterr().err
    assert str(path) in err
    if target == "journal":
        assert ":12:" in err  # the line after the edited one names the break


def test_missing_chunk_is_named(run_copy, capsys):
    chunk = _first_chunk(run_copy)
    chunk.unlink()
    assert main(["verify", str(run_copy)]) == 1
    err = capsys.readouterr().err
    assert str(chunk) in err and "missing" in err


def test_not_a_run_folder_is_bad_input(tmp_path, capsys):
    assert main(["verify", str(tmp_path)]) == 2
    assert "manifest.json" in capsys.readouterr().err
