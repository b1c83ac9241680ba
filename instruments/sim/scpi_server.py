"""A line-oriented SCPI socket server on loopback, the base of the simulated supply, DMM and counter.

Each simulator supplies ``answer(line) -> reply | None`` (None: a setting, no
reply) and keeps an SCPI error queue (``SYST:ERR?``). The server is what a
``TCPIP0::127.0.0.1::PORT::SOCKET`` resource reaches, so the real driver (or
someone else's) talks to it exactly as to the instrument. ``no_reply`` and
``drop_connection`` faults are handled here for every simulator.
"""

from __future__ import annotations

import contextlib
import socket
import socketserver
import threading
from collections import deque

from gyrocal.instruments.sim.faults import FaultInjector

COMMON_FAULTS = ("no_reply", "drop_connection")


class ScpiError(Exception):
    """A command the simulated instrument refuses: queued as ``code,"message"``."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code, self.message = code, message


class SimulatedScpiInstrument:
    """Threaded TCP server; subclasses implement :meth:`answer`."""

    def __init__(self, faults: FaultInjector, idn: str, host: str = "127.0.0.1",
                 port: int = 0) -> None:
        self.faults, self.idn = faults, idn
        self._where = (host, port)
        self._server: socketserver.ThreadingTCPServer | None = None
        self._errors: deque[str] = deque(maxlen=20)
        self.lock = threading.RLock()
        #: every line received, in order (tests read it to see what a driver sent)
        self.received: list[str] = []
        #: what stopped the simulator, if anything did (the serving threads answer each request
        #: on its own; none keeps running state that can die, so this stays None)
        self.error: BaseException | None = None

    def reseed(self, seed) -> None:
        """Draw from ``seed`` from here (the simulated station reseeds per attempt); the
        readings of the DMM and counter come from the shared model's source, so nothing."""

    @property
    def port(self) -> int:
        assert self._server is not None, "start() first"
        return int(self._server.server_address[1])

    @property
    def address(self) -> str:
        return f"TCPIP0::127.0.0.1::{self.port}::SOCKET"

    def answer(self, line: str) -> str | None:
        raise NotImplementedError

    def serve_line(self, line: str) -> str | None:
        """The reply to one line (common queries first), errors queued as SCPI does."""
        with self.lock:
            self.received.append(line)
            head = line.strip().upper()
            if head == "*IDN?":
                return self.idn
            if head in ("SYST:ERR?", "SYSTEM:ERROR?", "SYST:ERR:NEXT?"):
                return self._errors.popleft() if self._errors else '+0,"No error"'
            if head in ("*CLS",):
                self._errors.clear()
                return None
            if head in ("*RST", "*OPC"):
                return None
            if head == "*OPC?":
                return "1"
            try:
                return self.answer(line.strip())
            except ScpiError as exc:
                self._errors.append(f'{exc.code:+d},"{exc.message}"')
                return None

    def start(self):
        sim = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                for raw in self.rfile:
                    replies = []   # a compound line (a;b?;c?) is answered on one line, as SCPI does
                    for line in raw.decode("latin-1").strip().split(";"):
                        if not line.strip():
                            continue
                        if sim.faults.take("drop_connection") is not None:
                            with contextlib.suppress(OSError):
                                self.request.shutdown(socket.SHUT_RDWR)
                            return
                        reply = sim.serve_line(line)
                        if reply is not None:
                            replies.append(reply)
                    if replies and sim.faults.take("no_reply") is None:
                        self.wfile.write(";".join(replies).encode("latin-1") + b"\n")

        class Server(socketserver.ThreadingTCPServer):
            allow_reuse_address = True
            daemon_threads = True

        self._server = Server(self._where, Handler)
        threading.Thread(target=self._server.serve_forever, daemon=True,
                         name=f"sim-scpi-{self.port}").start()
        return self

    def stop(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._server = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
