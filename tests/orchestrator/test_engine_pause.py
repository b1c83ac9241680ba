"""Operator pause: `touch RUN_DIR/PAUSE` holds the run before the next step, safely."""

import json
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from gyrocal.cli import EXIT_OK, main


@pytest.mark.timeout(120)
def test_a_pause_file_holds_the_run_with_the_table_stopped_until_it_is_removed(
        h: Any, tmp_path: Path, sim_capture: Any, capsys) -> None:
    out = tmp_path / "run"
    seen: dict[str, Any] = {}

    def operator() -> None:
        journal = out / "journal.jsonl"
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            lines = journal.read_text().splitlines() if journal.exists() else []
            if any(json.loads(line)["event"] == "paused" for line in lines):
                break
            time.sleep(0.05)
        time.sleep(0.3)                      # the run must stay held meanwhile
        sim = sim_capture.last
        seen["table_mode"] = sim.table_physics.mode
        seen["table_rate_dps"] = float(sim.table_physics.rate_dps())
        seen["manifest_state"] = json.loads((out / "manifest.json").read_text())["state"]
        seen["events"] = [json.loads(line)["event"] for line in journal.read_text().splitlines()]
        (out / "PAUSE").unlink()

    procedure = h.write_procedure(tmp_path)

    def touch_when_started() -> None:
        """The operator pauses as soon as the run folder exists (the run makes it)."""
        deadline = time.monotonic() + 60
        while not (out / "manifest.json").exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        (out / "PAUSE").touch()
        operator()

    thread = threading.Thread(target=touch_when_started, daemon=True)
    thread.start()
    assert main(["run", str(procedure), "--sim", "--out", str(out)],
                on_sim_started=sim_capture) == EXIT_OK
    thread.join(10)
    assert seen["manifest_state"] == "paused"
    assert seen["table_mode"] == "off" and seen["table_rate_dps"] == pytest.approx(0.0, abs=1e-9)
    assert seen["events"][-1] == "paused"    # nothing happened while held
    events = h.events(out)
    names = [e["event"] for e in events]
    assert names.count("paused") == 1 and names.count("unpaused") == 1
    assert names.index("unpaused") == names.index("paused") + 1
    assert set(h.completed_ids(out)) == set(h.SMALL_PLAN)
