"""A small run record written by hand (no engine, no simulator): the report builder's input.

Three ± rate pairs and a static hold at two temperatures, with a known scale
factor and bias, in a real run folder (manifest, plan.json, journal, Parquet).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from gyrocal.record.journal import Journal, JournalEvent
from gyrocal.record.run_folder import RunFolder

FS_HZ = 50.0
LATITUDE = 50.46
EARTH_DPH = 15.041067 * math.sin(math.radians(LATITUDE))      # 11.600 deg/h
# truth: SF 1.0002 at 0 °C and 1.0006 at 40 °C; bias 3 deg/h + Earth rate at both
TRUTH = {0.0: (1.0002, 3.0), 40.0: (1.0006, 3.0)}


def write_run(tmp_path: Path) -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "p.yaml").write_text("# hand-made\n")
    folder = RunFolder.create(tmp_path / "run", tmp_path / "p.yaml", None)
    steps, n = [], int(10 * FS_HZ)
    with Journal(folder.path / "journal.jsonl") as journal:
        journal.append(JournalEvent.RUN_STARTED)
        for k, (temp, (sf, bias_dph)) in enumerate(TRUTH.items()):
            for kind, rate in (("static", 0.0), ("dwell", 10.0), ("dwell", -10.0),
                               ("dwell", 100.0), ("dwell", -100.0)):
                step_id = f"T{k + 1:02d}.{kind}{rate:+g}"
                steps.append({"step_id": step_id, "kind": kind, "rate_dps": rate,
                              "setpoint_c": temp, "temp_index": k, "revolutions": None,
                              "mounting": None})
                t = np.arange(n) / FS_HZ
                gyro = sf * (rate + (bias_dph + EARTH_DPH) / 3600.0) + np.zeros(n)
                columns = {"t_s": t, "table_rate_dps": np.full(n, rate),
                           "chamber_temp_c": np.full(n, temp), "gyro": gyro,
                           "sensor_temp_c": np.full(n, temp), "table_angle_deg": rate * t}
                chunk = folder.write_chunk(step_id, 1, 0, columns)
                journal.append(JournalEvent.STEP_STARTED, step_id=step_id, kind=kind, attempt=1)
                journal.append(JournalEvent.CHUNK_WRITTEN, step_id=step_id, attempt=1,
                               path=chunk.path, sha256=chunk.sha256, rows=chunk.rows)
                journal.append(JournalEvent.STEP_COMPLETED, step_id=step_id, attempt=1,
                               samples=n, lost_frames=0, crc_errors=0, chunks=[chunk.path])
    plan = {"version": 1, "procedure": {"name": "hand-made", "file": "p.yaml"},
            "unit_under_test": {"serial": "HAND-1", "nominal_scale_factor": 1.0},
            "acceptance": [{"name": "asym", "metric": "asymmetry_ppm", "max": 1.0, "min": None,
                            "unit": "ppm"}],
            "sample_rate_hz": FS_HZ, "station": {"name": "bench", "site": {"latitude_deg": LATITUDE}},
            "steps": steps}
    (folder.path / "plan.json").write_text(json.dumps(plan))
    return folder.path
