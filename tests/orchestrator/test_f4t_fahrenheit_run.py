"""A whole run against a simulated F4T as shipped: Display Units F (F4T guide p. 225).

The simulator serves register 1328 = 30 (F) and every temperature and set
point in °F, as the manual's factory default says; the driver reads the
units at connect and converts. Before issue 8 the run would have commanded
25 (°F: −3.9 °C) for 25 °C and soaked at the wrong temperature.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from gyrocal.cli import EXIT_OK, main


def test_a_run_on_a_fahrenheit_f4t_holds_its_celsius_setpoints(h: Any, tmp_path: Path,
                                                               sim_capture: Any) -> None:
    procedure = h.write_procedure(tmp_path)
    station = tmp_path / "station.yaml"
    text = station.read_text()
    assert "driver: watlow_f4  " in text or "driver: watlow_f4\n" in text
    text = re.sub(r"\n  limit_input: .*", "", text)           # an F4 setting: not for an F4T
    text = text.replace("serial: 12-3456", "serial: '1234567'")  # the F4T's serial (issue 11 checks it)
    station.write_text(text.replace("driver: watlow_f4 ", "driver: watlow_f4t ", 1))
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out)],
                on_sim_started=sim_capture) == EXIT_OK
    sim = sim_capture.last
    assert type(sim.chamber_server).__name__ == "SimulatedWatlowF4T"
    assert sim.chamber_server.display_units == 30                  # still °F on the wire
    events = h.events(out)
    identified = next(e for e in events if e["event"] == "instrument_identified"
                      and e["role"] == "chamber")
    assert "display units °F" in identified["description"]
    # the chamber physics (°C) reached every setpoint the procedure gave in °C
    plan = json.loads((out / "plan.json").read_text())
    setpoints = sorted({s["setpoint_c"] for s in plan["steps"]})
    results = json.loads((out / "report" / "results.json").read_text())
    measured = sorted(e["chamber_temp_c"] for e in results["scale_factor"])
    assert all(abs(m - s) < 1.0 for m, s in zip(measured, setpoints, strict=True)), (measured, setpoints)
    assert results["verdict"]["overall"] == "PASS"
