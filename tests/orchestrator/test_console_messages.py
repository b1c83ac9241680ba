"""What the console says when instruments do not answer, or answer in another protocol (issue 28).

Measured before: with the chamber and the table unreachable, eight near-identical
"attempt N failed … retrying" lines, then "TABLE/CHAMBER NOT CONFIRMED SAFE —
check it by hand" although nothing had been commanded; a chamber address that
reached a web server printed its answer as ~90 hex bytes. Real transports here:
closed loopback ports, a loopback TCP server that answers HTTP, a pty for the gyro.
"""

from __future__ import annotations

import io
import json
import os
import socket
import threading
from pathlib import Path

import pytest
import yaml

from gyrocal.cli import EXIT_FAULT, main
from gyrocal.instruments.errors import InstrumentTimeout, describe_reply
from gyrocal.orchestrator.retry_console import RetryConsole
from gyrocal.record.locks import LOCK_DIR_ENV

pytestmark = pytest.mark.timeout(120)
REPO = Path(__file__).resolve().parents[2]


def _closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]       # nothing listens once it is closed


class HttpAnswerer:
    """A loopback TCP server that answers whatever arrives as a web server would (RFC 9110 §15.5.1)."""

    REPLY = (b"HTTP/1.1 400 Bad Request\r\nServer: test\r\nContent-Type: text/html\r\n"
             b"Content-Length: 50\r\nConnection: close\r\n\r\n<html><body>400 Bad Request</body>"
             b"</html>\n\n\n\n\n\n\n\n")

    def __init__(self) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            with client:
                client.settimeout(2)
                try:
                    client.recv(4096)
                    client.sendall(self.REPLY)
                except OSError:
                    pass

    def close(self) -> None:
        self.server.close()


def _station(tmp_path: Path, chamber: str) -> tuple[Path, tuple[int, int]]:
    pty = os.openpty()
    station = yaml.safe_load((REPO / "stations" / "sim.yaml").read_text())
    station["chamber"]["address"] = chamber
    station["table"]["address"] = f"TCPIP0::127.0.0.1::{_closed_port()}::SOCKET"
    station["gyro"]["port"] = os.ttyname(pty[1])
    station["simulation"]["gyro_model"] = str(REPO / "gyro-models" / "nominal-fog.yaml")
    path = tmp_path / "station.yaml"
    path.write_text(yaml.safe_dump(station, sort_keys=False))
    return path, pty


def _run(tmp_path: Path, station: Path, capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["run", str(REPO / "procedures" / "smoke.yaml"), "--station", str(station),
                 "--out", str(tmp_path / "run"), "--allow-outside-paths"])
    return code, capsys.readouterr().err


def test_unreachable_instruments_give_one_retry_line_and_say_nothing_was_commanded(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    station, pty = _station(tmp_path, f"socket://127.0.0.1:{_closed_port()}")
    try:
        code, err = _run(tmp_path, station, capsys)
    finally:
        os.close(pty[0])
        os.close(pty[1])
    assert code == EXIT_FAULT, err
    retry_lines = [line for line in err.splitlines() if "retried" in line]
    assert len(retry_lines) == 1 and "retried 2 times" in retry_lines[0], err   # retries: 3
    assert "attempt 1 failed" not in err and "attempt 2 failed" not in err
    assert "nothing was commanded" in err and "NOT CONFIRMED SAFE" not in err, err
    journal = (tmp_path / "run" / "journal.jsonl").read_text()
    assert journal.count('"event":"retry"') == 2                  # the record keeps each one


def test_a_reply_in_another_protocol_is_described_not_dumped(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    web = HttpAnswerer()
    station, pty = _station(tmp_path, f"socket://127.0.0.1:{web.port}")
    try:
        code, err = _run(tmp_path, station, capsys)
    finally:
        web.close()
        os.close(pty[0])
        os.close(pty[1])
    assert code == EXIT_FAULT, err
    assert "not a Modbus reply: 'HTTP/1.1 400 Bad Request'" in err, err
    assert "48 54 54 50" not in err                                # "HTTP" as hex


def test_describe_reply_and_the_retry_console_collapse() -> None:
    assert describe_reply(b"HTTP/1.1 400 Bad Request\r\nServer: x\r\n", "Modbus") == \
        "not a Modbus reply: 'HTTP/1.1 400 Bad Request'…"
    assert describe_reply(bytes(range(40)), "Modbus") == \
        bytes(range(16)).hex(" ") + " … (40 bytes)"
    assert describe_reply(b"\x01\x83\x02\xc0\xf1", "Modbus") == "01 83 02 c0 f1"
    out = io.StringIO()
    console = RetryConsole(out)
    for _ in range(8):
        console.note("table", InstrumentTimeout("table", "*IDN?", "no reply"))
    console.note("chamber", InstrumentTimeout("chamber", "read 100", "no reply"))
    console.flush()
    assert out.getvalue().splitlines() == [
        "gyrocal: table: *IDN?: no reply; retried 8 times",
        "gyrocal: chamber: read 100: no reply; retried once"]


class CutAfterProxy:
    """A loopback TCP relay to ``target`` that goes silent from the first request starting
    with ``cut_at`` on: that request and every later one (on any connection) get no reply,
    as a chamber whose cable is pulled at that moment."""

    def __init__(self, target: tuple[str, int], cut_at: bytes) -> None:
        self.target, self.cut_at = target, cut_at
        self.cut = threading.Event()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.server.accept()
                upstream = socket.create_connection(self.target)
            except OSError:
                return
            threading.Thread(target=self._pipe, args=(client, upstream, True), daemon=True).start()
            threading.Thread(target=self._pipe, args=(upstream, client, False), daemon=True).start()

    def _pipe(self, source: socket.socket, sink: socket.socket, requests: bool) -> None:
        try:
            while data := source.recv(65536):
                if requests and data.startswith(self.cut_at):
                    self.cut.set()
                if not self.cut.is_set():
                    sink.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        self.server.close()


#: The first request of the chamber's preflight status read, after identify (which reads
#: registers 0-2, 606 and 901): Modbus RTU, unit 1, function 0x03 "Read Holding Registers"
#: from register 200 (0x00C8) — Modbus Application Protocol V1.1b3 §6.3 (function code,
#: starting address hi/lo); Modbus over Serial Line V1.02 §2.5.1 (address field first).
#: Register 200 is the F4's run state (instruments/chamber/watlow_f4.py, "profile_state").
READ_RUN_STATE = bytes([0x01, 0x03, 0x00, 0xC8])


def test_a_chamber_lost_in_preflight_after_identify_says_nothing_was_commanded(
        tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch, fork_server) -> None:
    """Issue 28: the instruments identified, then the chamber stops answering at preflight's
    first status read. Nothing has been commanded yet, so the console says so (and the run
    commands no safe state into a rig it never drove), never "NOT CONFIRMED SAFE"."""
    from tests.orchestrator.test_locks import write_live_procedure
    from tests.support.sim_serve import served_station

    monkeypatch.setenv(LOCK_DIR_ENV, str(tmp_path / "locks"))
    with served_station(tmp_path / "live-station.yaml", server=fork_server) as live:
        station = yaml.safe_load(live.read_text())
        chamber_port = int(station["chamber"]["address"].rsplit(":", 1)[1])
        proxy = CutAfterProxy(("127.0.0.1", chamber_port), READ_RUN_STATE)
        station["chamber"]["address"] = f"socket://127.0.0.1:{proxy.port}"
        cut = tmp_path / "cut-station.yaml"
        cut.write_text(yaml.safe_dump(station, sort_keys=False))
        try:
            capsys.readouterr()
            code = main(["run", str(write_live_procedure(tmp_path, live)), "--station", str(cut),
                         "--out", str(tmp_path / "run")])
            err = capsys.readouterr().err
        finally:
            proxy.close()
    assert proxy.cut.is_set(), err           # the chamber went silent where the test meant
    assert code == EXIT_FAULT, err
    assert "nothing was commanded" in err and "NOT CONFIRMED SAFE" not in err, err
    events = [json.loads(line)["event"] for line in
              (tmp_path / "run" / "journal.jsonl").read_text().splitlines()]
    assert events.count("instrument_identified") == 3 and "preflight_ok" not in events
    safe = [json.loads(line) for line in (tmp_path / "run" / "journal.jsonl").read_text()
            .splitlines() if '"event":"safe_state"' in line]
    assert len(safe) == 1 and safe[0]["commanded"] is False and safe[0]["actions"] == {}
