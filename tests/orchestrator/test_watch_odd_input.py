"""`watch` and `status` on odd input: malformed requests, clients that hang up, damaged folders (issue 28).

Measured before: garbage request lines were answered with a bare error page and
no status line (the standard library's HTTP/0.9 fallback), clients that reset
the connection printed tracebacks on the ``watch`` console, and a run folder
whose ``manifest.json`` is a list made ``status`` exit with an internal error.
Each request here is raw bytes on a real socket to a ``gyrocal watch`` process.
"""

from __future__ import annotations

import json
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gyrocal.cli import EXIT_BAD_INPUT, EXIT_OK, main

pytestmark = pytest.mark.timeout(120)
REPO = Path(__file__).resolve().parents[2]

#: (raw request, the status the server must answer). RFC 9112 §3: a request line is
#: method SP request-target SP HTTP-version; §2.3: HTTP-version is "HTTP/" DIGIT "." DIGIT.
MALFORMED = [
    (b"garbage\r\n\r\n", 400),
    (b"\x00\xff\xfe\x16\x03\x01\r\n\r\n", 400),           # binary (a TLS hello on a plain port)
    (b"GET / HTTP/1.1x\r\n\r\n", 400),
    (b"GET / HTTP/1.\r\n\r\n", 400),
    (b"GET / HTTP/-1.1\r\n\r\n", 400),
    (b"GET / FOO/1.0\r\n\r\n", 400),
    (b"GET / HTTP/1.1 extra\r\n\r\n", 400),
    (b"GET / HTTP/\xd9\xa1.\xd9\xa1\r\n\r\n", 400),      # Arabic-Indic digits are not DIGIT
    (b"GET / HTTP/9.9\r\n\r\n", 505),                     # well formed, a version not served
    (b"GET / HTTP/1.1\r\nX: " + b"a" * 70000 + b"\r\n\r\n", 431),
]


def _run_folder(folder: Path) -> Path:
    folder.mkdir()
    (folder / "manifest.json").write_text(json.dumps({"run_id": "R1", "state": "done"}))
    return folder


def _start_watch(run_dir: Path) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, "-m", "gyrocal", "watch", str(run_dir), "--port", "0"],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert "http://127.0.0.1:" in line, proc.stderr.read()
    return proc, int(line.split("http://127.0.0.1:")[1].split("/")[0])


def _exchange(port: int, request: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(request)
        reply = b""
        while chunk := sock.recv(65536):
            reply += chunk
    return reply


def _stop(proc: subprocess.Popen) -> str:
    proc.send_signal(2)       # Ctrl-C, as a person would
    _, err = proc.communicate(timeout=60)
    return err


def test_malformed_requests_get_a_status_line_and_hang_ups_are_ignored(tmp_path: Path) -> None:
    proc, port = _start_watch(_run_folder(tmp_path / "run"))
    try:
        for request, status in MALFORMED:
            reply = _exchange(port, request)
            assert reply.startswith(f"HTTP/1.0 {status} ".encode()), (request[:40], reply[:80])
        for _ in range(20):   # a reset (SO_LINGER 0) while the 51 KB script is being sent
            sock = socket.create_connection(("127.0.0.1", port))
            sock.sendall(b"GET /uPlot.iife.min.js HTTP/1.1\r\n\r\n")
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            sock.close()
        time.sleep(0.5)
        assert _exchange(port, b"GET /api/snapshot HTTP/1.0\r\n\r\n").startswith(b"HTTP/1.0 200 ")
    finally:
        err = _stop(proc)
    assert proc.returncode == 0
    assert "Traceback" not in err and "Exception" not in err, err


DAMAGE = {
    "manifest a list": ("manifest.json", lambda run: (run / "manifest.json").write_text("[1, 2]")),
    "manifest a folder": ("manifest.json", lambda run: ((run / "manifest.json").unlink(),
                                                       (run / "manifest.json").mkdir())),
    "manifest steps a number": ("manifest.json", lambda run: (run / "manifest.json").write_text(
        json.dumps({"run_id": "R1", "state": "running", "steps": 7}))),
    "plan a string": ("plan.json", lambda run: (run / "plan.json").write_text('"steps"')),
    "plan steps of numbers": ("plan.json", lambda run: (run / "plan.json").write_text(
        json.dumps({"steps": [1, 2]}))),
    "journal a folder": ("journal.jsonl", lambda run: (run / "journal.jsonl").mkdir()),
    "journal not JSON": ("journal.jsonl", lambda run: (run / "journal.jsonl").write_bytes(
        b'{"seq": 1}\n\xff\xfe not json\n')),
    "samples a file": ("samples", lambda run: ((run / "samples").write_text("x"),
                                               _journal_chunk(run))),
    "chunk not Parquet": ("attempt1-chunk00000.parquet", lambda run: (
        (run / "samples" / "T01").mkdir(parents=True),
        (run / "samples" / "T01" / "attempt1-chunk00000.parquet").write_text("not parquet"),
        _journal_chunk(run))),
}


STATUS_NEVER_READS = {"samples", "attempt1-chunk00000.parquet"}


def _journal_chunk(run: Path) -> None:
    line = {"seq": 1, "wall_time": time.time(), "event": "chunk_written", "step_id": "T01",
            "attempt": 1, "path": "samples/T01/attempt1-chunk00000.parquet"}
    (run / "journal.jsonl").write_text(json.dumps(line) + "\n")


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_status_and_watch_describe_a_damaged_folder_naming_the_file(
        tmp_path: Path, capsys, case: str) -> None:
    named, damage = DAMAGE[case]
    run = _run_folder(tmp_path / "run")
    damage(run)
    capsys.readouterr()
    if named in STATUS_NEVER_READS:     # status reads no samples: it still answers
        assert main(["status", str(run)]) == EXIT_OK
    else:
        assert main(["status", str(run)]) == EXIT_BAD_INPUT
        err = capsys.readouterr().err
        assert named in err and "Traceback" not in err and "internal error" not in err, err

    from gyrocal.app.watch.server import WatchServer

    if case == "manifest a folder":   # refused at start, as status refuses it
        assert main(["watch", str(run), "--port", "0"]) == EXIT_BAD_INPUT
        assert "manifest.json" in capsys.readouterr().err
        return
    server = WatchServer(run, port=0).start()
    try:
        reply = _exchange(server.httpd.server_address[1], b"GET /api/snapshot HTTP/1.0\r\n\r\n")
    finally:
        server.stop()
    head, _, body = reply.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.0 503 "), reply[:200]
    assert named in json.loads(body)["error"]


def test_status_of_a_path_that_is_not_a_folder_is_bad_input(tmp_path: Path, capsys) -> None:
    (tmp_path / "file").write_text("x")
    for target in (tmp_path / "file", tmp_path / "missing", Path(os.devnull)):
        assert main(["status", str(target)]) == EXIT_BAD_INPUT
        assert "not a run folder" in capsys.readouterr().err
