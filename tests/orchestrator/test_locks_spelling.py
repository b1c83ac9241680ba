"""Station locks keyed on the instrument, not on how its address is spelled (issue 28).

Measured before: a second controller naming the simulated table as
``localhost`` while the first named it ``127.0.0.1`` got past preflight and
started a step; the first run then faulted ("table in mode 'off'") mid-dwell.
Here, against ``gyrocal sim serve`` (real servers on loopback, a real pty):
the second controller is refused before anything is commanded, whether it
spells the same endpoints differently or reaches the chamber through another
endpoint altogether (a TCP relay: same serial), and the first run finishes
and verifies with no fault in its journal.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

from gyrocal.cli import EXIT_FAULT, EXIT_OK, main
from gyrocal.instruments.address import instrument_keys
from gyrocal.record.locks import LOCK_DIR_ENV
from tests.orchestrator.test_locks import wait_for, write_live_procedure
from tests.support.fork_server import Forked, ForkServer
from tests.support.sim_serve import served_station, stop
from tests.support.tcp_proxy import ExchangeProxy

pytestmark = pytest.mark.timeout(150)
REPO = Path(__file__).resolve().parents[2]


def test_spellings_of_one_endpoint_share_a_key_and_other_endpoints_do_not(tmp_path: Path) -> None:
    def meet(role: str, a: str, b: str) -> bool:
        return bool(set(instrument_keys(role, a)) & set(instrument_keys(role, b)))

    assert meet("table", "TCPIP0::127.0.0.1::5025::SOCKET", "TCPIP::localhost::5025::SOCKET")
    assert meet("chamber", "socket://127.0.0.1:5020", "socket://localhost:5020")
    assert meet("chamber", "127.0.0.1:502", "LOCALHOST")          # F4T: a bare host means 502
    assert not meet("table", "TCPIP0::127.0.0.1::5025::SOCKET", "TCPIP0::127.0.0.1::5026::SOCKET")
    device = tmp_path / "ttyUSB0"
    device.touch()
    (tmp_path / "by-id").symlink_to(device)
    assert meet("gyro", str(device), str(tmp_path / "by-id"))
    assert meet("gyro", str(device), str(tmp_path / "." / "ttyUSB0"))
    assert instrument_keys("gyro", str(device)) == (f"dev:{device}",)


def _respelled(live: Path, out: Path, **changes: str) -> Path:
    data = yaml.safe_load(live.read_text())
    for dotted, value in changes.items():
        section, key = dotted.split("__")
        data[section][key] = value
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def _first_run(tmp_path: Path, procedure: Path, live: Path, env: dict[str, str],
               server: ForkServer) -> Forked:
    """The first controller, forked from the warm fork server (a process of its own)."""
    first = server.start(["run", str(procedure), "--station", str(live),
                          "--out", str(tmp_path / "first")], env, tmp_path / "first.err")
    # preflight passed: the first controller holds every lock and commands the rig
    wait_for(lambda: (tmp_path / "first" / "journal.jsonl").exists() and
             '"preflight_ok"' in (tmp_path / "first" / "journal.jsonl").read_text(), first)
    return first


def _first_finishes_untouched(first: Forked, tmp_path: Path) -> None:
    _, stderr = first.communicate(timeout=120)
    assert first.returncode in (0, 1), stderr
    journal = (tmp_path / "first" / "journal.jsonl").read_text()
    assert '"event":"fault"' not in journal and '"event":"retry"' not in journal
    assert main(["verify", str(tmp_path / "first")]) == EXIT_OK


def _other_spelling(station: dict, role: str) -> str:
    if role == "gyro":   # /dev/pts/N as /dev/../dev/pts/./N (a station file needs /dev/…)
        return "/dev/../dev/pts/./" + Path(station["gyro"]["port"]).name
    return station[role]["address"].replace("127.0.0.1", "localhost")


@pytest.mark.slow
@pytest.mark.parametrize("role", ["table", "chamber", "gyro"])
def test_a_second_controller_spelling_an_instrument_differently_is_refused_before_any_command(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, role: str, fork_server) -> None:
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    env = {**os.environ}
    first = None
    own_pty = os.openpty()
    with served_station(tmp_path / "live-station.yaml", env=env, server=fork_server) as live:
        try:
            procedure = write_live_procedure(tmp_path, live)
            station = yaml.safe_load(live.read_text())
            # the two others elsewhere (free), so only the respelled one can refuse
            elsewhere = {"chamber": "socket://127.0.0.1:9", "table": "TCPIP0::127.0.0.1::9::SOCKET",
                         "gyro": os.ttyname(own_pty[1])}
            elsewhere[role] = _other_spelling(station, role)
            other = _respelled(live, tmp_path / "other-spelling.yaml",
                               chamber__address=elsewhere["chamber"],
                               table__address=elsewhere["table"], gyro__port=elsewhere["gyro"])
            first = _first_run(tmp_path, procedure, live, env, fork_server)
            capsys.readouterr()
            code = main(["run", str(procedure), "--station", str(other),
                         "--out", str(tmp_path / "second")])
            err = capsys.readouterr().err
            assert code == EXIT_FAULT, err
            assert f"pid {first.pid}" in err and "in use" in err
            assert f"{role} at {elsewhere[role]}" in err, err        # names the spelling
            assert not (tmp_path / "second").exists()   # refused before a folder or a command
            _first_finishes_untouched(first, tmp_path)
        finally:
            os.close(own_pty[0])
            os.close(own_pty[1])
            if first is not None:
                stop(first)


@pytest.mark.slow
def test_a_second_controller_reaching_the_chamber_by_another_endpoint_meets_its_serial(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, fork_server) -> None:
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    env = {**os.environ}
    first = None
    with served_station(tmp_path / "live-station.yaml", env=env, server=fork_server) as live:
        station = yaml.safe_load(live.read_text())
        chamber_port = int(station["chamber"]["address"].rsplit(":", 1)[1])
        relay = ExchangeProxy(("127.0.0.1", chamber_port))    # another endpoint, same chamber
        own_pty = os.openpty()
        try:
            procedure = write_live_procedure(tmp_path, live)
            other = _respelled(
                live, tmp_path / "via-relay.yaml",
                chamber__address=f"socket://127.0.0.1:{relay.port}",
                table__address="TCPIP0::127.0.0.1::9::SOCKET",   # never reached
                gyro__port=os.ttyname(own_pty[1]))                # a pty of our own
            first = _first_run(tmp_path, procedure, live, env, fork_server)
            capsys.readouterr()
            code = main(["run", str(procedure), "--station", str(other),
                         "--out", str(tmp_path / "second")])
            err = capsys.readouterr().err
            os.close(own_pty[0])
            os.close(own_pty[1])
            assert code == EXIT_FAULT, err
            assert f"pid {first.pid}" in err and "chamber serial 12-3456" in err, err
            assert "nothing was commanded" in err
            second = (tmp_path / "second" / "journal.jsonl").read_text()
            assert '"state":"connecting"' in second and '"preflight_ok"' not in second
            _first_finishes_untouched(first, tmp_path)
        finally:
            relay.close()
            if first is not None:
                stop(first)
