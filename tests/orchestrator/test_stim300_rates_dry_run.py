"""Issue 23: a simulated 0x93 unit at 125 Hz and 250 Hz runs the smoke procedure with no repeated step.

Before the counter rule (TS1524 §7.5.2.2.18: the counter counts 2000 Hz
internal samples, so it steps 16 at 125 Hz and 8 at 250 Hz) every step
below 2000 Hz read as lost frames and was repeated, then faulted. The
journal is the witness: every step started once, completed, no bad step,
no lost frame; the chunks carry the accelerometer and inclinometer columns.
"""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_OK, main

pytestmark = pytest.mark.timeout(300)
REPO = Path(__file__).resolve().parents[2]


def write_inputs(tmp_path: Path, fs_hz: int) -> Path:
    station = (REPO / "stations" / "sim.yaml").read_text(encoding="utf-8")
    station = station.replace("  sample_rate_hz: 2000", f"  sample_rate_hz: {fs_hz}")
    station = station.replace("  with_temperature: true", "  datagram: 0x93\n  accelerometer_range_g: 30")
    station = station.replace("../gyro-models/nominal-fog.yaml",
                              str(REPO / "gyro-models" / "nominal-fog.yaml"))
    (tmp_path / "station.yaml").write_text(station, encoding="utf-8")
    smoke = (REPO / "procedures" / "smoke.yaml").read_text(encoding="utf-8")
    smoke = smoke.replace("  sample_rate_hz: 2000", f"  sample_rate_hz: {fs_hz}")
    smoke = smoke.replace("station: ../stations/sim.yaml", "station: station.yaml")
    path = tmp_path / "smoke.yaml"
    path.write_text(smoke, encoding="utf-8")
    return path


@pytest.mark.parametrize("fs_hz", [125, 250])
def test_smoke_dry_run_with_a_0x93_unit_repeats_no_step(tmp_path, capsys, fs_hz):
    out = tmp_path / "run"
    code = main(["run", str(write_inputs(tmp_path, fs_hz)), "--sim", "--out", str(out),
                 "--allow-outside-paths"])
    assert code == EXIT_OK, capsys.readouterr()
    events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    started = [e for e in events if e["event"] == "step_started"]
    completed = [e for e in events if e["event"] == "step_completed"]
    assert "step_bad" not in kinds and "gyro_implausible" not in kinds and "fault" not in kinds
    assert {e["attempt"] for e in started} == {1}
    assert len({e["step_id"] for e in started}) == len(started) == len(completed) > 0
    logged = [e for e in completed if "samples" in e]
    assert logged and all(e["lost_frames"] == 0 and e["crc_errors"] == 0 for e in logged)
    gyro = next(e for e in events if e["event"] == "instrument_identified" and e["role"] == "gyro")
    assert "0x93 (rate, acceleration, inclination)" in gyro["description"]
    assert f"counter step {2000 // fs_hz}" in gyro["description"]
    # asked at connect (C<CR>, TS1524 §8.3), the simulated unit states its configuration
    configuration = next(e for e in events if e["event"] == "gyro_configuration")
    assert configuration["confirmed"] is True and configuration["sample_rate_hz"] == fs_hz
    assert (configuration["datagram"], configuration["crlf"]) == ("0x93", False)
    assert configuration["gyro_output_unit"] == "angular rate [°/s]"
    assert configuration["accelerometer_range_g"] == [30, 30, 30]
    identified = [e for e in events if e["event"] == "instrument_identified" and e["role"] == "gyro"]
    assert "configuration confirmed (C, TS1524 §8.3)" in identified[-1]["description"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert "configuration confirmed" in manifest["instruments"]["gyro"]["description"]
    results = json.loads((out / "report" / "results.json").read_text())
    assert "configuration confirmed" in json.dumps(results["instruments"]["gyro"], ensure_ascii=False)
    chunk = pq.read_table(out / logged[0]["chunks"][0])
    assert chunk.num_rows == logged[0]["samples"] and logged[0]["samples"] > 0
    for name in ("acc_x_g", "acc_y_g", "acc_z_g", "incl_x_g", "incl_y_g", "incl_z_g",
                 "acc_status", "incl_status"):
        assert name in chunk.column_names
    assert chunk["acc_z_g"].to_numpy().mean() == pytest.approx(1.0, abs=2.0**-18)
    assert "kind" in started[0] and "run_completed" in kinds
