"""``gyrocal station check`` against live instruments: exit 0 when all fit, 3 naming each problem.

- Against ``gyrocal sim serve`` in its own process (the whole simulated station).
- Against pymodbus's stock server holding a Watlow F4's registers as the F4P
  manual lays them out (model 0, serial 1-2, input 100, set point 300, units
  901, decimals 606; digital input 1 status 201 and condition 1061, pp. 9.2-9.5
  and 9.11), with the limit controller tripped — status equal to condition —
  and an F4T running its own profile (16568 = 149, Espec watlowf4t.py).
- Against the simulated table with its safety chain broken (``:Interlock?``
  answers Fault).
Nothing is ever commanded: the chamber's registers are compared before and after.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
import yaml
from pymodbus.framer import FramerType

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main
from gyrocal.instruments.sim.table_server import SimulatedAcutrol
from gyrocal.models.clock import SimClock
from gyrocal.models.table import TablePhysics
from tests.support.modbus_stock_server import StockServer
from tests.support.sim_serve import served_station
from tests.support.ubc_captures import SLOW

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.timeout(120)


def station_with(tmp_path: Path, **sections: dict) -> Path:
    """stations/sim.yaml with the named sections' keys replaced (addresses of live peers)."""
    data = yaml.safe_load((REPO / "stations" / "sim.yaml").read_text())
    for name, values in sections.items():
        data[name].update(values)
    data["simulation"]["gyro_model"] = str(REPO / "gyro-models" / "nominal-fog.yaml")
    path = tmp_path / "station.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.slow
def test_the_simulated_station_is_fit_and_reported(tmp_path: Path, capsys, fork_server) -> None:
    out = tmp_path / "check.json"
    with served_station(tmp_path / "live.yaml", server=fork_server) as live:
        station = yaml.safe_load(live.read_text())
        code = main(["station", "check", str(live), "--json", str(out)])
    printed = capsys.readouterr()
    assert code == EXIT_OK, printed
    report = json.loads(out.read_text())
    assert report["ok"] is True and report["problems"] == []
    chamber = report["instruments"]["chamber"]["facts"]
    assert chamber["units"] == "°C" and chamber["decimals"] == 1
    assert chamber["alarm"] is False and chamber["profile_running"] is False
    assert 15.0 < chamber["process_value_c"] < 35.0
    table = report["instruments"]["table"]["facts"]
    assert table["identity"].count(",") == 3 and table["interlock"] in ("Open", "Close")
    assert table["mode"] == "off" and abs(table["rate_dps"]) < 0.05
    gyro = report["instruments"]["gyro"]["facts"]
    assert gyro["frames_valid"] > 0 and gyro["crc_errors"] == 0 and gyro["lost_frames"] == 0
    assert gyro["sample_rate_hz_by_counter"] == station["gyro"]["sample_rate_hz"]
    assert gyro["datagram"].startswith("0x94") and gyro["gyro_status_bits_seen"] == "0x00"
    assert len(gyro["gyro_mean"]) == 3
    assert gyro["configuration_confirmed"] is True
    assert "configuration confirmed (C, TS1524 §8.3)" in gyro["configuration"]
    assert "every instrument fit for a run" in printed.out


F4_HEALTHY = {0: 5270, 1: 12, 2: 3456, 100: 231, 300: 250, 200: 1, 201: 0, 1061: 1,
              606: 1, 901: 1}                       # 23.1 °C, set point 25.0 °C, tenths, °C


def test_a_tripped_limit_on_a_stock_server_chamber_is_named_exit_3(tmp_path: Path, capsys) -> None:
    tripped = {**F4_HEALTHY, 201: 1}                  # status = condition: the input is active
    with StockServer(tripped, FramerType.RTU) as peer:
        station = station_with(tmp_path, chamber={"address": f"socket://127.0.0.1:{peer.port}"})
        before = [peer.hr(a, 100) for a in range(0, 1100, 100)]
        code = main(["station", "check", str(station), "--only", "chamber",
                     "--json", str(tmp_path / "c.json")])
        assert [peer.hr(a, 100) for a in range(0, 1100, 100)] == before   # nothing written
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "chamber: alarm active (alarm: limit controller tripped (digital input 1))" in err
    report = json.loads((tmp_path / "c.json").read_text())
    assert report["instruments"]["chamber"]["facts"]["process_value_c"] == pytest.approx(23.1)
    assert list(report["instruments"]) == ["chamber"]


def test_the_same_chamber_healthy_is_fit(tmp_path: Path, capsys) -> None:
    with StockServer(F4_HEALTHY, FramerType.RTU) as peer:
        station = station_with(tmp_path, chamber={"address": f"socket://127.0.0.1:{peer.port}"})
        code = main(["station", "check", str(station), "--only", "chamber"])
    out = capsys.readouterr().out
    assert code == EXIT_OK, out
    assert "setpoint_c: 25.0" in out and "alarm: False" in out


def test_an_f4t_running_its_own_profile_is_named(tmp_path: Path, capsys) -> None:
    def float_lwf(value: float) -> list[int]:
        high, low = struct.unpack(">HH", struct.pack(">f", value))
        return [low, high]
    registers = {1328: 15, 90: 138, 1356: 61, 16568: 149}   # °C, OK, no alarm, profile running
    registers.update(dict(zip((2782, 2783), float_lwf(25.0), strict=True)))
    registers.update(dict(zip((2820, 2821), float_lwf(24.5), strict=True)))
    with StockServer(registers, FramerType.SOCKET) as peer:
        station = station_with(tmp_path, chamber={"driver": "watlow_f4t", "limit_input": None,
                                                  "address": f"127.0.0.1:{peer.port}"})
        text = station.read_text().replace("  limit_input: null\n", "")
        station.write_text(text)
        code = main(["station", "check", str(station), "--only", "chamber"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "chamber: the controller runs its own profile (profile running)" in err


def test_a_table_with_its_interlock_faulted_is_named(tmp_path: Path, capsys) -> None:
    physics = TablePhysics(SimClock(), max_rate_dps=600.0, max_accel_dps2=100.0)
    with SimulatedAcutrol(physics) as table:
        table.faults.arm("interlock_open", count=None)
        station = station_with(tmp_path, table={"address": table.resource})
        code = main(["station", "check", str(station), "--only", "table"])
        assert table.interpreter.remote_lockout is False      # no change, not even the lockout
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "table: interlock fault" in err


def test_an_instrument_that_does_not_answer_is_a_problem_not_a_traceback(tmp_path, capsys):
    station = station_with(tmp_path, chamber={"address": "socket://127.0.0.1:9", "timeout_s": 0.2,
                                              "retries": 1})
    code = main(["station", "check", str(station), "--only", "chamber"])
    err = capsys.readouterr().err
    assert code == EXIT_FAULT
    assert "chamber: no usable answer:" in err and "Traceback" not in err


@pytest.mark.slow
def test_a_0x93_unit_at_250_hz_then_a_wrong_declaration(tmp_path: Path, capsys,
                                                         fork_server) -> None:
    """TS1524: 0x93 carries rate, acceleration and inclination (Table 5-21); at 250 Hz the
    counter steps 8 (§7.5.2.2.18). Declared right: fit, with the accelerometer and
    inclinometer means (a level unit: about +1 g on one axis), its configuration confirmed by
    its answer to C. Declared 0x94: exit 3 naming what the unit is configured for and what the
    station declares."""
    station = station_with(tmp_path, gyro={"datagram": 0x93, "sample_rate_hz": 250,
                                           "with_temperature": False})
    with served_station(tmp_path / "live.yaml", station=str(station), server=fork_server) as live:
        code = main(["station", "check", str(live), "--only", "gyro", "--json",
                     str(tmp_path / "g.json")])
        first = capsys.readouterr()     # whole, for the message below (a repr is cut short)
        wrong = tmp_path / "wrong.yaml"
        wrong.write_text(live.read_text().replace("datagram: 147", "datagram: 148")
                         .replace("with_temperature: false", "with_temperature: true"))
        assert "datagram: 148" in wrong.read_text()
        code_wrong = main(["station", "check", str(wrong), "--only", "gyro"])
    printed = capsys.readouterr()
    assert code == EXIT_OK, f"declared right, yet:\n{first.out}\n{first.err}"
    gyro = json.loads((tmp_path / "g.json").read_text())["instruments"]["gyro"]["facts"]
    assert gyro["datagram"].startswith("0x93") and gyro["counter_step"] == 8
    # N<CR>, I<CR> (TS1524 §8.1-8.2): `sim serve` is given no procedure, so no serial to say
    assert gyro["unit"] == ("unit part number 84167-0000000-S0M rev G, serial: not confirmed "
                            "(no answer to I, TS1524 §8.2)")
    assert gyro["sample_rate_hz_by_counter"] == 250.0
    assert max(abs(a) for a in gyro["accelerometer_mean_g"]) == pytest.approx(1.0, abs=0.05)
    assert len(gyro["inclinometer_mean_g"]) == 3
    assert code_wrong == EXIT_FAULT
    # the unit's own answer to C<CR> (TS1524 §8.3) names it first, before the stream is surveyed
    assert ("the unit is configured for datagram 0x93 (rate, acceleration, inclination) (TS1524 "
            "Table 5-16 byte 3, Table 5-21); the station declares 0x94 (rate, temperature)"
            in printed.err)
    assert gyro["configuration_confirmed"] is True
    assert "gyro output angular rate [°/s]" in gyro["configuration"]


def test_a_station_with_sim_addresses_is_bad_input(capsys) -> None:
    code = main(["station", "check", str(REPO / "stations" / "sim.yaml")])
    assert code == EXIT_BAD_INPUT
    assert "sim serve --write-station" in capsys.readouterr().err


def test_a_replayed_unit_does_not_answer_c_and_that_is_said_not_faulted(tmp_path: Path, capsys,
                                                                          fork_server) -> None:
    """A replayed capture is one-way: no answer to C<CR> within the bound is no fault (the
    stream's own type stands); the check says the configuration is not confirmed."""
    out = tmp_path / "g.json"
    with served_station(tmp_path / "live.yaml", extra_args=("--replay-gyro", str(SLOW)), server=fork_server) as live:
        code = main(["station", "check", str(live), "--only", "gyro", "--json", str(out)])
    printed = capsys.readouterr()
    assert code == EXIT_OK, printed
    gyro = json.loads(out.read_text())["instruments"]["gyro"]["facts"]
    assert gyro["configuration_confirmed"] is False
    assert gyro["unit"] == ("unit part number, serial: not confirmed (not asked: no answer to C, "
                            "TS1524 §8.3)")
    assert gyro["configuration"] == "configuration not confirmed: no answer to C (TS1524 §8.3)"
    assert "configuration not confirmed: no answer to C (TS1524 §8.3)" in printed.out
    assert gyro["datagram"].startswith("0x93")
