"""What the console says when instruments do not answer, or answer in another protocol (issue 28).

Measured before: with the chamber and the table unreachable, eight near-identical
"attempt N failed … retrying" lines, then "TABLE/CHAMBER NOT CONFIRMED SAFE —
check it by hand" although nothing had been commanded; a chamber address that
reached a web server printed its answer as ~90 hex bytes. Real transports here:
closed loopback ports, a loopback TCP server that answers HTTP, a pty for the gyro.
"""

from __future__ import annotations

import io
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
