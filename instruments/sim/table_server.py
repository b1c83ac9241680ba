"""A simulated ACUTROL3000 rate table: a real ACL socket server on loopback.

The driver reaches it through pyvisa-py exactly as it reaches a real table's
``TCPIP0::host::9878::SOCKET`` resource, so dry runs exercise the same code
path as the lab. Each line received (LF-terminated, TM-8004 §2.4) is one
*request* and gets one reply framed as TM-8004 §2 / TM-9374A §3.4.2 describe:
error code and message length as two little-endian 32-bit words, then the
message and a NUL (``acutrol_protocol.frame_reply``). The injected faults act
on requests:

``drop_connection``  the request is not executed; the connection is reset (RST),
                     as when the table's controller reboots or a switch drops the link.
``no_reply``         it is executed, the reply is lost.
``late_reply``       the reply is sent ``delay_s`` (default 1 s) late.
``garbled_reply``    the reply's message arrives corrupted (the framing intact).
``error_reply``      the first *setting* command of the request is refused with error code
                     ``code`` (default 5, the simulator's "Execution error"); with
                     ``bad_message: true`` it is flagged in ``*ESR?`` bit 2 as a bad message.
``interlock_open``   persistent until cleared: the safety chain is open, so the interlock
                     reads open, motion is refused, a spinning table stops and
                     ``:interlock:close`` fails. Applied at the next request (or at
                     :meth:`SimulatedAcutrol.apply_persistent_faults`); after clearing it
                     the interlock stays open until closed by command, as on a real table.

"""

from __future__ import annotations

import contextlib
import socket
import socketserver
import struct
import threading

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.table_acl import ERR_EXECUTION, AcutrolInterpreter, parse_line
from gyrocal.instruments.table.acutrol_protocol import DEFAULT_DIALECT, DIALECTS, frame_reply
from gyrocal.models.table import TablePhysics

FAULTS = (
    "no_reply",
    "late_reply",
    "drop_connection",
    "garbled_reply",
    "interlock_open",
    "error_reply",
)

DEFAULT_IDN = "ACUTRONIC,ACUTROL3000-SIM,SIM0001,1.0"
_GARBLE = str.maketrans("0123456789.-,;", "O!Z3A5G7B9#~%$")


def garble(message: str) -> str:
    """Corrupt a message the way line noise would: control byte first, characters swapped."""
    return "\x15" + message.translate(_GARBLE)


class _Server(socketserver.ThreadingTCPServer):
    allow_reuse_address = True
    daemon_threads = False
    block_on_close = True

    def __init__(self, address: tuple[str, int], sim: SimulatedAcutrol) -> None:
        self.sim = sim
        super().__init__(address, _Connection)


class _Connection(socketserver.BaseRequestHandler):
    """One client connection: read lines, answer them, honour the faults."""

    server: _Server

    def handle(self) -> None:
        sim = self.server.sim
        sock: socket.socket = self.request
        if not sim._register(sock):
            return
        buffer = b""
        try:
            while not sim._stopping.is_set():
                try:
                    chunk = sock.recv(4096)
                except OSError:
                    return
                if not chunk:
                    return
                buffer += chunk
                while b"\n" in buffer:
                    raw, buffer = buffer.split(b"\n", 1)
                    line = raw.decode("latin-1").strip()
                    if line and not sim._serve_line(sock, line):
                        return
        finally:
            sim._unregister(sock)


class SimulatedAcutrol:
    """ACUTROL3000 (ACL over TCP) rate-table server answering from ``physics`` at the clock's now."""

    def __init__(
        self,
        physics: TablePhysics,
        faults: FaultInjector | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        idn: str = DEFAULT_IDN,
        dialect: str = DEFAULT_DIALECT,
    ) -> None:
        if dialect not in DIALECTS:
            raise ValueError(f"simulated table: dialect must be one of {list(DIALECTS)}, got {dialect!r}")
        self.dialect = dialect
        self.physics = physics
        self.faults = faults if faults is not None else FaultInjector(FAULTS, owner="simulated table")
        unknown = set(self.faults.known) - set(FAULTS)
        if unknown:
            raise ValueError(f"simulated table: fault injector knows unsupported faults {unknown}")
        self.interpreter = AcutrolInterpreter(physics, idn)
        self._address = (host, port)
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None
        self._clients: set[socket.socket] = set()
        self._clients_lock = threading.Lock()
        self._stopping = threading.Event()
        self._line_lock = threading.Lock()

    # ----- lifecycle ----------------------------------------------------------------------

    @property
    def host(self) -> str:
        return self._address[0]

    @property
    def port(self) -> int:
        if self._server is None:
            raise RuntimeError("simulated table: not started, no port yet")
        return int(self._server.server_address[1])

    @property
    def resource(self) -> str:
        return f"TCPIP0::{self.host}::{self.port}::SOCKET"

    def start(self) -> SimulatedAcutrol:
        if self._server is None:
            self._stopping.clear()
            self._server = _Server(self._address, self)
            self._thread = threading.Thread(
                target=self._server.serve_forever,
                kwargs={"poll_interval": 0.05},
                name=f"sim-table-{self.port}",
                daemon=True,
            )
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop listening, close every client socket, and wait for the handlers to end."""
        server, self._server = self._server, None
        if server is None:
            return
        self._stopping.set()
        server.shutdown()
        with self._clients_lock:
            clients = list(self._clients)
        for sock in clients:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
        server.server_close()  # joins the connection threads
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def __enter__(self) -> SimulatedAcutrol:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ----- faults -------------------------------------------------------------------------

    def apply_persistent_faults(self) -> None:
        """Bring the table in line with persistent faults (the broken safety chain) now."""
        chain_open = self.faults.is_armed("interlock_open")
        self.interpreter.safety_chain_open = chain_open
        if chain_open and self.physics.interlock_closed:
            self.faults.take("interlock_open")  # journal the moment it acted
            self.physics.open_interlock()

    # ----- request handling (connection threads) ------------------------------------------

    def _register(self, sock: socket.socket) -> bool:
        with self._clients_lock:
            if self._stopping.is_set():
                return False
            self._clients.add(sock)
            return True

    def _unregister(self, sock: socket.socket) -> None:
        with self._clients_lock:
            self._clients.discard(sock)

    def _serve_line(self, sock: socket.socket, line: str) -> bool:
        """Answer one request; False when the connection must end."""
        with self._line_lock:  # one request at a time, like the controller's parser
            self.apply_persistent_faults()
            if self.faults.take("drop_connection") is not None:
                _reset(sock)
                return False
            commands = parse_line(line)
            refused = 0
            if any(c.is_setting for c in commands):
                refusal = self.faults.take("error_reply")
                if refusal is not None:
                    refused = int(refusal.get("code", ERR_EXECUTION[0]))
                    if refusal.get("bad_message"):
                        self.interpreter.latch_bad_message()
                    del commands[next(i for i, c in enumerate(commands) if c.is_setting)]
            code, message = self.interpreter.execute_line(commands)
        return self._send(sock, refused or code, message)

    def _send(self, sock: socket.socket, code: int, message: str) -> bool:
        if self.faults.take("no_reply") is not None:
            return True
        late = self.faults.take("late_reply")
        if late is not None and self._stopping.wait(float(late.get("delay_s", 1.0))):
            return False
        if self.faults.take("garbled_reply") is not None:
            message = garble(message)
        try:
            sock.sendall(frame_reply(code, message))
        except OSError:
            return False
        return True


def _reset(sock: socket.socket) -> None:
    """Close with RST rather than FIN: the client sees the connection reset at once."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        sock.close()
