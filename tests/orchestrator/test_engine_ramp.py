"""The chamber follows the procedure's ramp rate, whatever the controller's own settings."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gyrocal.cli import EXIT_OK, main


@pytest.mark.timeout(120)
def test_setpoint_walks_to_each_temperature_at_the_procedure_ramp_rate(
        h: Any, tmp_path: Path, sim_capture: Any) -> None:
    writes: list[tuple[float, float]] = []

    def record(sim: Any) -> None:
        physics = sim.chamber_physics
        original = physics.set_setpoint

        def set_setpoint(value_c: float) -> None:
            writes.append((sim.clock.now_s(), float(value_c)))
            original(value_c)

        physics.set_setpoint = set_setpoint

    sim_capture.arm.append(record)
    procedure = h.write_procedure(tmp_path)
    procedure.write_text(procedure.read_text().replace("ramp_c_per_min: 5.0", "ramp_c_per_min: 2.0"))
    assert main(["run", str(procedure), "--sim", "--out", str(tmp_path / "run")],
                on_sim_started=sim_capture) == EXIT_OK

    t, sp = np.array(writes).T
    # the ramp to 27 °C: from the 23 °C soak, at 2 °C/min, ending exactly on the target
    up = np.flatnonzero(sp > 23.0)
    up = up[: np.flatnonzero(sp[up] >= 27.0)[0] + 1]
    # the F4 holds the setpoint to 0.1 °C: each write is on the 2 °C/min line within that
    line_c = sp[up[0]] + 2.0 / 60.0 * (t[up] - t[up[0]])
    assert np.all(np.abs(sp[up[:-1]] - line_c[:-1]) <= 0.1 + 1e-9)
    assert sp[up[-1]] == 27.0
    assert (t[up[-1]] - t[up[0]]) / 60.0 == pytest.approx((27.0 - sp[up[0]]) / 2.0, abs=0.3)
    assert len(up) >= 10          # walked in steps, not commanded at once
