"""Samples the gyro itself flags (saturated, in error) are bad data, never calibration data.

Regressions of issue 8: a ``gyro.saturate`` rehearsal produced SF 2.57 (the
flagged full-scale samples were averaged into a dwell) and
``gyro.saturate:always`` crashed the report with ZeroDivisionError. Now a
flagged sample counts like a lost frame, is kept on disk with its status
but left out of the analysis, and a step with too many of them is repeated
and then faults (exit 3, safe state).
"""

import json
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
import pytest

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.models.gyro_model import load_model

pytestmark = pytest.mark.timeout(180)


def sf_truth(sensor_temp_c: float) -> float:
    """The simulated gyro's scale factor at a sensor temperature (the nominal-FOG model)."""
    model = load_model(Path(__file__).resolve().parents[2] / "gyro-models" / "nominal-fog.yaml")
    return 1.0 + 1e-6 * (model.sf_error_ppm + model.sf_tempco_ppm_per_c
                         * (sensor_temp_c - model.reference_temp_c))


def test_an_always_saturated_gyro_repeats_the_step_then_faults_safe(h: Any, tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["run", str(h.write_procedure(tmp_path, max_repeats=2)), "--sim", "--out", str(out),
                 "--inject", "gyro.saturate:always@T01.sf.+20dps"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT, err
    assert "ZeroDivisionError" not in err and "Traceback" not in err
    events = h.events(out)
    bad = [e for e in events if e["event"] == "step_bad" and e["step_id"] == "T01.sf.+20dps"]
    assert [e["attempt"] for e in bad] == [1, 2, 3]
    assert all(e["flagged_samples"] > 0 and "flagged saturated/error" in e["reason"] for e in bad)
    fault = [e for e in events if e["event"] == "fault"][-1]
    assert fault["step_id"] == "T01.sf.+20dps"
    assert not any(e["event"] == "report_written" for e in events)
    assert "T01.sf.+20dps" not in h.completed_ids(out)


def saturate_one_frame_inside_the_step(h: Any, sim: Any) -> None:
    """One saturated frame in a block that starts 3 s after the +20 deg/s command.

    That is inside the step's logged 8 s (after the 0.2 s spin-up and 1 s settle,
    whose frames the engine flushes): armed at the step's start, a fault would fire
    in a block the flush discards.
    """
    port, source = sim.gyro_port, sim.gyro_port.source
    port.span_block_frames = port.block_frames      # the 512-frame blocks counted on here
    state = {"from_s": None, "armed": False}

    def start() -> None:
        state["from_s"] = sim.clock.now_s() + 3.0

    def saturating_source(t_s):
        if state["from_s"] is not None and not state["armed"] and t_s[0] >= state["from_s"]:
            sim.gyro_faults.arm("saturate", count=1)
            state["armed"] = True
        return source(t_s)

    port.source = saturating_source
    h.when_table_commanded(sim, 20.0, start)


def test_a_single_saturated_sample_is_logged_flagged_and_left_out_of_the_sf(
        h: Any, tmp_path: Path, sim_capture: Any) -> None:
    out = tmp_path / "run"
    sim_capture.arm.append(lambda sim: saturate_one_frame_inside_the_step(h, sim))
    code = main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out)],
                on_sim_started=sim_capture)
    assert code == EXIT_OK
    events = h.events(out)
    done = {e["step_id"]: e for e in events if e["event"] == "step_completed"}
    assert done["T01.sf.+20dps"]["flagged_samples"] == 1
    # On disk: the full-scale sample is there, with its status byte and flag.
    table = pq.read_table(out / done["T01.sf.+20dps"]["chunks"][0]).to_pydict()
    flagged_rows = [i for i, s in enumerate(table["status"]) if s != 0]
    assert len(flagged_rows) == 1
    row = flagged_rows[0]
    assert table["gyro_status"][row] == 0x11            # datasheet: overload (bit 4) on x (bit 0)
    assert table["gyro"][row] == pytest.approx((2**23 - 1) * 2.0**-14)
    assert table["gyro_x"][row] == table["gyro"][row]
    # In the analysis: the scale factor is the model's, not dragged by a 512 deg/s sample
    # (2.57 before; one such sample in 2000 would move it by 0.6 %).
    results = json.loads((out / "report" / "results.json").read_text())
    for entry in results["scale_factor"]:
        assert entry["sf"] == pytest.approx(sf_truth(entry["sensor_temp_c"]), abs=2e-4)
