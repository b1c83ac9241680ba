"""What a logged step holds: only samples taken under that step's conditions, correctly labelled."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gyrocal.analysis.measured_log import read_run_folder_log
from gyrocal.cli import EXIT_OK, main
from gyrocal.models.gyro_model import load_model

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("sample_rate_hz", [250, 2000])
def test_every_sample_of_a_step_was_taken_at_that_steps_rate(h: Any, tmp_path: Path,
                                                            sample_rate_hz: int) -> None:
    """A frame produced before the table changed rate must never open the next step.

    The simulated gyro runs ahead of its reader and the clock jumps while the
    table spins up and settles; the samples of each dwell must nevertheless
    all show the dwell's rate (within the gyro's noise), and the logged table
    rate must be that rate.
    """
    procedure = h.write_procedure(tmp_path)
    text = procedure.read_text().replace("sample_rate_hz: 250", f"sample_rate_hz: {sample_rate_hz}")
    procedure.write_text(text)
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out), "--seed", "3"]) == EXIT_OK
    log = read_run_folder_log(out)
    model = load_model(REPO / "gyro-models" / "nominal-fog.yaml")
    white_dps = model.noise.arw_deg_per_rth * 60 * np.sqrt(sample_rate_hz) / 3600
    lsb_dps = 2.0**-14
    for step in dict.fromkeys(log.segment):
        rows = log.segment == step
        rate = log.table_rate_dps[rows]
        assert np.all(rate == rate[0]), step
        error_dps = log.gyro[rows] - rate[0] * model.scale_factor
        # bias + SF error are < 0.01 deg/s here; a stale sample would be 20 deg/s off
        assert np.max(np.abs(error_dps - np.median(error_dps))) < 6 * white_dps + 2 * lsb_dps, step
        t = log.t_s[rows]
        assert np.allclose(np.diff(t), 1.0 / sample_rate_hz), step
