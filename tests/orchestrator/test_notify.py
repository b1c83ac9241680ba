"""Station ``notify:`` targets: a dry run's fault reaches a real SMTP server and a webhook.

The sinks are not ours: aiosmtpd (the Python project's SMTP server) receives
the e-mail apprise sends, and the standard library's HTTP server receives the
webhook's POST. A target that cannot be reached is journaled as failed and
the run goes on.
"""

from __future__ import annotations

import email
import json
import socket
import threading
from http.server import BaseHTTPRequestHandler, HTTPServer
from pathlib import Path
from typing import Any

import pytest
from aiosmtpd.controller import Controller

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_OK, main


class MailSink:
    def __init__(self) -> None:
        self.messages: list[email.message.Message] = []
        self.envelopes: list[Any] = []

    async def handle_DATA(self, server, session, envelope) -> str:  # noqa: N802 - aiosmtpd API
        self.envelopes.append(envelope)
        self.messages.append(email.message_from_bytes(envelope.content))
        return "250 OK"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def smtp_sink():
    sink = MailSink()
    controller = Controller(sink, hostname="127.0.0.1", port=_free_port())
    controller.start()
    yield sink, controller.port
    controller.stop()


@pytest.fixture
def http_sink():
    posts: list[tuple[str, dict]] = []

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:  # noqa: N802 - stdlib API
            body = self.rfile.read(int(self.headers["Content-Length"]))
            posts.append((self.path, json.loads(body)))
            self.send_response(200)
            self.end_headers()

        def log_message(self, *args: object) -> None:
            pass

    server = HTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield posts, server.server_address[1]
    server.shutdown()
    server.server_close()


def _with_notify(h: Any, tmp_path: Path, notify_yaml: str) -> Path:
    procedure = h.write_procedure(tmp_path)
    station = tmp_path / "station.yaml"
    station.write_text(station.read_text() + "\nnotify:\n" + notify_yaml)
    return procedure


def test_a_fault_in_a_dry_run_is_mailed_and_posted(h: Any, tmp_path: Path, smtp_sink,
                                                   http_sink) -> None:
    mail, smtp_port = smtp_sink
    posts, http_port = http_sink
    procedure = _with_notify(h, tmp_path, f"""
  - url: mailto://127.0.0.1:{smtp_port}?from=gyrocal@lab.example&to=oncall@lab.example
    on: [faulted, needs_operator]
  - url: json://127.0.0.1:{http_port}/hooks/gyrocal
    on: [finished, faulted]
""")
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out),
                 "--inject", "table.interlock_open:always@T02.sf.+20dps"]) == EXIT_FAULT
    assert len(mail.messages) == 1
    message = mail.messages[0]
    assert mail.envelopes[0].rcpt_tos == ["oncall@lab.example"]
    assert "SIM-T" in message["Subject"] and "faulted" in message["Subject"]
    text = message.get_payload(decode=True) if not message.is_multipart() else \
        message.get_payload(0).get_payload(decode=True)
    assert b"T02.sf.+20dps" in text and b"interlock" in text.lower()
    assert len(posts) == 1 and posts[0][0] == "/hooks/gyrocal"
    assert "faulted" in posts[0][1]["title"] and "T02.sf.+20dps" in posts[0][1]["message"]
    notified = [e for e in h.events(out) if e["event"] == "notified"]
    assert [(e["on"], e["ok"]) for e in notified] == [("faulted", True), ("faulted", True)]
    assert notified[0]["target"] == f"mailto://127.0.0.1:{smtp_port}"


def test_a_failed_notification_is_journaled_and_the_run_goes_on(h: Any, tmp_path: Path,
                                                               http_sink) -> None:
    posts, http_port = http_sink
    procedure = _with_notify(h, tmp_path, f"""
  - url: json://127.0.0.1:{_free_port()}/nobody-listens
    on: [finished]
  - command: [sh, -c, 'echo "$0 $1" >&2; exit 4']
    on: [finished]
  - url: json://127.0.0.1:{http_port}/ok
    on: [finished]
""")
    out = tmp_path / "run"
    assert main(["run", str(procedure), "--sim", "--out", str(out)]) == EXIT_OK
    notified = [e for e in h.events(out) if e["event"] == "notified"]
    assert [(e["on"], e["ok"]) for e in notified] == [("finished", False), ("finished", False),
                                                      ("finished", True)]
    assert notified[1]["error"].startswith("exit 4: finished")
    assert len(posts) == 1 and "finished" in posts[0][1]["title"]
    assert main(["verify", str(out)]) == EXIT_OK    # the extra events keep the chain whole


@pytest.mark.parametrize(("target", "words"), [
    ("  - {url: mailto://x:25, on: [exploded]}", "unknown event 'exploded'"),
    ("  - {url: not-a-url}", "apprise URL"),
    ("  - {url: 'json://a/b', command: [true]}", "exactly one of url"),
    ("  - {command: true}", "non-empty list of strings"),
])
def test_bad_notify_targets_are_refused_with_their_key(h: Any, tmp_path: Path, capsys,
                                                       target: str, words: str) -> None:
    procedure = _with_notify(h, tmp_path, target + "\n")
    assert main(["validate", str(procedure)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert words in err and "notify" in err and "Traceback" not in err
