"""A run whose station contradicts what the unit says when asked (``C<CR>``, TS1524 §8.3).

The real path: ``gyrocal run --station`` against ``gyrocal sim serve``, whose simulated
STIM300 (0x93, accelerometers ±30 g) answers C with its configuration datagram; the station
is edited to declare ±10 g. The datagram type the stream shows is right, so only the unit's
own statement (TS1524 Table 5-16 bytes 17–18) can tell: a fault at connect, exit 3, naming
both values and the table, before any step starts or the table is commanded to move.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from gyrocal.cli import EXIT_FAULT, main
from tests.support.sim_serve import served_station

pytestmark = pytest.mark.timeout(240)
REPO = Path(__file__).resolve().parents[2]


def test_an_accelerometer_range_the_unit_contradicts_is_a_fault_at_connect(tmp_path, capsys,
                                                                           fork_server):
    data = yaml.safe_load((REPO / "stations" / "sim.yaml").read_text(encoding="utf-8"))
    data["gyro"].pop("with_temperature", None)
    data["gyro"].update(datagram=0x93, accelerometer_range_g=30)
    data["simulation"]["gyro_model"] = str(REPO / "gyro-models" / "nominal-fog.yaml")
    served = tmp_path / "served.yaml"
    served.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    live = tmp_path / "live.yaml"
    with served_station(live, station=str(served), server=fork_server):
        text = live.read_text(encoding="utf-8")
        assert "accelerometer_range_g: 30" in text
        wrong = tmp_path / "wrong.yaml"
        wrong.write_text(text.replace("accelerometer_range_g: 30", "accelerometer_range_g: 10"),
                         encoding="utf-8")
        out = tmp_path / "run"
        code = main(["run", str(REPO / "procedures" / "smoke.yaml"), "--station", str(wrong),
                     "--out", str(out), "--allow-outside-paths"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT, err
    assert ("the unit's accelerometer range is ±30/30/30 g on x/y/z (TS1524 Table 5-16 bytes "
            "17–18); the station declares ±10 g") in err
    assert "Traceback" not in err
    events = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    assert "fault" in kinds and "step_started" not in kinds and "preflight_ok" not in kinds
    assert "nothing was commanded: the instruments are as they were found" in err
    said = next(e for e in events if e["event"] == "gyro_configuration")
    assert said["answered"] is True and said["confirmed"] is False
    assert said["accelerometer_range_g"] == [30, 30, 30] and len(said["contradictions"]) == 1
    gyro = [e for e in events if e["event"] == "instrument_identified" and e["role"] == "gyro"]
    assert len(gyro) == 1 and "configuration contradicts the station" in gyro[0]["description"]
    assert "continue with `gyrocal resume" in err
