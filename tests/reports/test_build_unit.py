"""The report builder on a small run record written by hand, numbers worked by hand.

Three ± rate pairs at two temperatures and a static hold, written straight
into a run folder (manifest, plan.json, journal, Parquet chunks) with a
known scale factor and bias: no engine, no simulator, no procedure. The
expected figures are computed below from the numbers typed here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gyrocal.reports.build import compute_results, read_run
from tests.support.hand_run import EARTH_DPH, TRUTH, write_run


def test_numbers_follow_from_the_hand_made_record(tmp_path: Path) -> None:
    notes: list[str] = []
    results = compute_results(read_run(write_run(tmp_path), notes), notes).to_json()
    by_temp = {e["temp_c"]: e for e in results["scale_factor"]}
    for temp, (sf, _) in TRUTH.items():
        assert by_temp[temp]["sf"] == pytest.approx(sf, abs=1e-12)
        assert by_temp[temp]["asymmetry_ppm"] == pytest.approx(0.0, abs=1e-6)
    # (1.0006 − 1.0002) / 40 °C, in ppm/°C of the 25 °C value: 10 ppm/°C to first order
    assert results["sf_temperature"]["sensitivity_ppm_per_c"] == pytest.approx(10.0, rel=1e-3)
    # static holds: mean / SF(T) · 3600 − Earth rate = the bias typed in
    assert [round(b["bias_dph"], 9) for b in results["bias"]] == [3.0, 3.0]
    assert results["bias_temperature"]["sensitivity_dph_per_c"] == pytest.approx(0.0, abs=1e-9)
    assert results["earth_rate_removed_dph"] == pytest.approx(EARTH_DPH, abs=1e-12)
    assert results["acceptance"][0]["pass"] is True
    assert results["imu"] is None


def test_a_record_without_sweeps_says_what_it_could_not_compute(tmp_path: Path) -> None:
    run = write_run(tmp_path)
    plan = json.loads((run / "plan.json").read_text())
    for s in plan["steps"]:
        if s["kind"] == "dwell":
            s["kind"] = "static"         # the dwells now count as holds, not sweeps
    (run / "plan.json").write_text(json.dumps(plan))
    notes: list[str] = []
    results = compute_results(read_run(run, notes), notes).to_json()
    assert results["scale_factor"] == [] and results["nonlinearity"] is None
    assert any("no ± rate sweep completed" in n for n in notes)


def test_samples_the_gyro_flagged_are_never_averaged_in(tmp_path: Path) -> None:
    """A chunk's status column (gyro saturated / in error) removes those rows from the figures."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    run = write_run(tmp_path)
    chunk = next((run / "samples" / "T01.dwell+10").glob("*.parquet"))
    table = pq.read_table(chunk)
    gyro = table.column("gyro").to_numpy().copy()
    status = np.zeros(len(gyro), np.uint8)
    gyro[:50], status[:50] = 400.0, 1            # saturated frames, flagged by the unit
    table = table.set_column(table.schema.get_field_index("gyro"), "gyro", pa.array(gyro))
    pq.write_table(table.append_column("status", pa.array(status)), chunk)
    notes: list[str] = []
    results = compute_results(read_run(run, notes), notes).to_json()
    sf0 = next(e for e in results["scale_factor"] if e["temp_c"] == 0.0)
    assert sf0["sf"] == pytest.approx(TRUTH[0.0][0], abs=1e-12)
    step = next(s for s in results["steps"] if s["step_id"] == "T01.dwell+10")
    assert step["n_logged"] == 450
