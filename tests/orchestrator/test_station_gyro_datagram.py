"""The station's gyro declaration: datagram (TS1524 Table 5-21) and accelerometer range."""

from __future__ import annotations

from pathlib import Path

import pytest

from gyrocal.orchestrator.station import load_station
from gyrocal.problems import ProcedureError

pytestmark = pytest.mark.timeout(30)
REPO = Path(__file__).resolve().parents[2]


def station_with(tmp_path: Path, gyro_lines: str) -> Path:
    text = (REPO / "stations" / "sim.yaml").read_text(encoding="utf-8")
    text = text.replace("  with_temperature: true\n", gyro_lines)
    text = text.replace("../gyro-models/nominal-fog.yaml", str(REPO / "gyro-models" / "nominal-fog.yaml"))
    path = tmp_path / "station.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("lines, datagram, temperature, range_g", [
    ("  with_temperature: true\n", 0x94, True, 10),
    ("  with_temperature: false\n", 0x90, False, 10),
    ("", 0x94, True, 10),
    ("  datagram: 0x93\n  accelerometer_range_g: 30\n", 0x93, False, 30),
    ("  datagram: '0xA7'\n", 0xA7, True, 10),
    ("  datagram: 0xF3\n  accelerometer_range_g: 80\n", 0xF3, False, 80),
])
def test_the_declared_datagram_and_range_load(tmp_path, lines, datagram, temperature, range_g):
    gyro = load_station(station_with(tmp_path, lines)).gyro
    assert (gyro.datagram, gyro.with_temperature, gyro.accelerometer_range_g) == (
        datagram, temperature, range_g)


@pytest.mark.parametrize("lines, message", [
    ("  datagram: 0x95\n", "0x95 is not a STIM300 normal-mode datagram"),
    ("  datagram: 0x93\n  with_temperature: true\n", "contradicts datagram 0x93"),
    ("  accelerometer_range_g: 20\n", "expected one of 5, 10, 30, 80"),
])
def test_a_wrong_declaration_is_named_with_its_line(tmp_path, lines, message):
    path = station_with(tmp_path, lines)
    with pytest.raises(ProcedureError) as error:
        load_station(path)
    text = str(error.value)
    assert message in text and "station.yaml:" in text
