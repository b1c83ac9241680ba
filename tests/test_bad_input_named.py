"""The named bad inputs of issue 28, each through the real command line: exit 2, located, no traceback.

Measured before: a NUL byte in a path named inside a procedure or station and a
model number of 1.0e+308 were internal errors (exit 3); a Parquet log whose
``t_s`` is a timestamp crashed, hung or grew memory; an acceptance ``max`` below
zero and a station naming a broken model file or an unreadable signing key were
called OK by ``validate`` and refused by ``run``.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main

REPO = Path(__file__).resolve().parents[1]
SMOKE = (REPO / "procedures" / "smoke.yaml").read_text()
STATION = (REPO / "stations" / "sim.yaml").read_text()
MODEL = (REPO / "gyro-models" / "nominal-fog.yaml").read_text()


def _project(tmp_path: Path, *, procedure: str = SMOKE, station: str = STATION,
             model: str = MODEL) -> Path:
    (tmp_path / "model.yaml").write_text(model)
    (tmp_path / "station.yaml").write_text(
        station.replace("../gyro-models/nominal-fog.yaml", "model.yaml"))
    path = tmp_path / "procedure.yaml"
    path.write_text(procedure.replace("../stations/sim.yaml", "station.yaml"))
    return path


def _validate(capsys, path: Path) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["validate", str(path)])
    text = capsys.readouterr().err
    assert "Traceback" not in text and "internal error" not in text, text
    return code, text


def test_the_unmutated_project_validates(tmp_path: Path, capsys) -> None:
    assert _validate(capsys, _project(tmp_path))[0] == EXIT_OK


@pytest.mark.parametrize("case, edit, expect", [
    ("NUL in station:", dict(procedure=SMOKE.replace("station: ../stations/sim.yaml",
                                                     'station: "station.yaml\\0x"')),
     r"procedure.yaml:\d+: station: .*control character '\\x00'"),
    ("NUL in gyro_model", dict(station=STATION.replace("../gyro-models/nominal-fog.yaml",
                                                       '"mod\\0el.yaml"')),
     r"station.yaml:\d+: simulation.gyro_model: .*control character"),
    ("model ARW 1.0e+308", dict(model=MODEL.replace("arw_deg_per_rth: 0.01",
                                                    "arw_deg_per_rth: 1.0e+308")),
     r"model.yaml:\d+: noise.arw_deg_per_rth: 1e\+308 is beyond"),
    ("acceptance max below zero", dict(procedure=SMOKE.replace("max: 1.0, unit: \"%\"}",
                                                               "max: -273.16, unit: \"%\"}", 1)),
     r"procedure.yaml:\d+: acceptance\[0\].max: max -273.16 can never be met"),
    ("serial beyond 64 characters", dict(procedure=SMOKE.replace("serial: SIM-0001",
                                                                 "serial: " + "X" * 65)),
     r"procedure.yaml:\d+: unit_under_test.serial: a serial number is at most 64"),
])
def test_named_bad_inputs_are_refused_at_validate_with_file_line_and_key(
        tmp_path: Path, capsys, case: str, edit: dict, expect: str) -> None:
    originals = {"procedure": SMOKE, "station": STATION, "model": MODEL}
    assert all(text != originals[name] for name, text in edit.items()), case   # the edit took
    code, text = _validate(capsys, _project(tmp_path, **edit))
    assert code == EXIT_BAD_INPUT, text
    assert re.search(expect, text), text


def test_a_signing_key_run_would_refuse_is_refused_by_validate(tmp_path: Path, capsys) -> None:
    key = tmp_path / "station.key"
    key.write_text("not a key")
    os.chmod(key, 0o600)
    station = STATION.replace("site:", f"signing_key: {key}\nsite:", 1)
    code, text = _validate(capsys, _project(tmp_path, station=station))
    assert code == EXIT_BAD_INPUT and "station.key" in text, text


def test_a_parquet_log_with_a_timestamp_t_s_is_refused_before_any_numeric_code(
        tmp_path: Path, capsys) -> None:
    n = 2000
    t_ns = (np.arange(n) * 1e7).astype("int64")
    table = pa.table({"t_s": pa.array(t_ns).cast(pa.timestamp("ns")),
                      "table_rate_dps": np.zeros(n), "chamber_temp_c": np.full(n, 25.0),
                      "gyro": np.random.default_rng(1).normal(0, 1e-3, n)})
    log = tmp_path / "log.parquet"
    pq.write_table(table, log)
    capsys.readouterr()
    code = main(["discrepancy", "--model", str(REPO / "gyro-models" / "nominal-fog.yaml"),
                 "--measured", str(log), "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT
    assert "log.parquet: column t_s: type timestamp[ns] is not a number" in err, err
    assert not (tmp_path / "d").exists()
