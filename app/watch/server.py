"""``gyrocal watch RUN_DIR``: a read-only live page for a run, from its folder alone.

The standard library's threaded HTTP server is enough for a handful of
people watching one run; the page polls ``/api/snapshot`` and draws with
uPlot, served from this package (``static/``), never from the internet.
Nothing here writes: only GET and HEAD are answered. On loopback no token
is needed; bound to any other address every request must carry the token
printed at start (``?token=…``), compared in constant time.
"""

from __future__ import annotations

import argparse
import hmac
import ipaddress
import json
import secrets
import sys
import threading
from functools import partial
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from gyrocal.app.watch.outcome import REPORT, read_outcome
from gyrocal.app.watch.samples import conditions, step_signal
from gyrocal.app.watch.snapshot import read_events, read_snapshot
from gyrocal.record.run_folder import RunFolderError

STATIC = Path(__file__).with_name("static")
_TYPES = {".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
          ".html": "text/html; charset=utf-8"}
_FILES = {"/": "page.html", "/page.js": "page.js", "/uPlot.iife.min.js": "uPlot.iife.min.js",
          "/uPlot.min.css": "uPlot.min.css"}


def is_loopback(bind: str) -> bool:
    try:
        return ipaddress.ip_address(bind).is_loopback
    except ValueError:
        return bind == "localhost"


def page_data(run_dir: Path) -> dict:
    """Everything the page shows, as one JSON document."""
    snap = read_snapshot(run_dir)
    events = read_events(run_dir)
    return {"snapshot": snap.to_json(), "conditions": conditions(run_dir, events, snap.plan),
            "signal": step_signal(run_dir, events), "outcome": read_outcome(run_dir).to_json()}


class WatchHandler(BaseHTTPRequestHandler):
    server_version = "gyrocal-watch"
    #: A request line that cannot be parsed is answered with a status line (400), not as
    #: HTTP/0.9 (a bare error page with no status, which the standard default would send).
    default_request_version = "HTTP/1.0"

    def __init__(self, *args, run_dir: Path, token: str | None, **kwargs) -> None:
        self.run_dir = run_dir
        self.token = token
        super().__init__(*args, **kwargs)

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - stdlib name
        pass   # a page polled every second would flood the terminal

    def _authorised(self, query: dict[str, list[str]]) -> bool:
        if self.token is None:
            return True
        given = (query.get("token") or [""])[0]
        return hmac.compare_digest(given.encode(), self.token.encode())

    def _send(self, status: int, body: bytes, ctype: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def do_GET(self) -> None:  # noqa: N802 - stdlib name
        url = urlsplit(self.path)
        if not self._authorised(parse_qs(url.query)):
            self._send(HTTPStatus.FORBIDDEN, b"token required\n", "text/plain")
            return
        if url.path == "/api/snapshot":
            try:
                body = json.dumps(page_data(self.run_dir), allow_nan=False, default=str)
            except (RunFolderError, ValueError) as exc:
                self._send(HTTPStatus.SERVICE_UNAVAILABLE, json.dumps(
                    {"error": str(exc)}).encode(), "application/json")
                return
            self._send(HTTPStatus.OK, body.encode(), "application/json")
            return
        if url.path == "/" + REPORT:      # the finished run's report, linked from the page
            report = self.run_dir / REPORT
            if report.is_file():
                self._send(HTTPStatus.OK, report.read_bytes(), _TYPES[".html"])
            else:
                self._send(HTTPStatus.NOT_FOUND, b"no report yet\n", "text/plain")
            return
        name = _FILES.get(url.path)
        if name is None:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")
            return
        path = STATIC / name
        self._send(HTTPStatus.OK, path.read_bytes(), _TYPES[path.suffix])

    do_HEAD = do_GET

    def _refuse(self) -> None:
        self._send(HTTPStatus.METHOD_NOT_ALLOWED, b"read-only\n", "text/plain")

    do_POST = do_PUT = do_DELETE = do_PATCH = _refuse


class QuietHTTPServer(ThreadingHTTPServer):
    """Clients that hang up are ignored; anything else is one line on the console, never a traceback.

    The standard server prints a traceback for every exception a request raises
    (``socketserver.BaseServer.handle_error``): a browser closing a tab mid-reply
    (BrokenPipe, ConnectionReset) filled the ``watch`` console. Malformed requests
    never get here: the handler answers them 400 (``BaseHTTPRequestHandler``).
    """

    daemon_threads = True

    def handle_error(self, request: object, client_address: tuple) -> None:
        exc = sys.exc_info()[1]
        if isinstance(exc, (ConnectionError, TimeoutError)):
            return
        print(f"gyrocal watch: request from {client_address[0]} failed: "
              f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)


class WatchServer:
    """The page's server, startable from a test or the command (port 0: any free port)."""

    def __init__(self, run_dir: Path, *, port: int = 0, bind: str = "127.0.0.1",
                 token: str | None = None) -> None:
        if not (Path(run_dir) / "manifest.json").is_file():
            raise RunFolderError(f"{run_dir}: not a run folder (manifest.json missing)")
        self.token = None if is_loopback(bind) else (token or secrets.token_urlsafe(18))
        handler = partial(WatchHandler, run_dir=Path(run_dir), token=self.token)
        self.httpd = QuietHTTPServer((bind, port), handler)
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/" + (f"?token={self.token}" if self.token else "")

    def start(self) -> WatchServer:
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


def cmd_watch(args: argparse.Namespace) -> int:
    server = WatchServer(Path(args.run_dir), port=args.port, bind=args.bind)
    print(f"watching {args.run_dir}: {server.url}  (read-only; Ctrl-C to stop)", flush=True)
    try:
        server.httpd.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.httpd.server_close()
    return 0
