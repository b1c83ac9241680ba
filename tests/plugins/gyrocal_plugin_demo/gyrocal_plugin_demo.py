"""A chamber driver from outside gyrocal, in one file: driver, simulator and spec.

The "Demo Chambers TC-1" is an imaginary controller speaking plain text over
TCP, one command a line, one reply a line::

    ID?         -> "Demo Chambers,TC-1,<serial>"
    TEMP?       -> air temperature, °C        SETP?   -> setpoint, °C
    SETP <c>    -> "OK"                       ALARM?  -> "0" or "1"

Published to gyrocal by the entry point (this folder's ``*.dist-info``)::

    [gyrocal.drivers]
    demo_chamber = gyrocal_plugin_demo:SPEC

It is what README "Add your instrument" walks through; the test
tests/instruments/test_plugin_driver.py validates and runs a procedure on it.
"""

from __future__ import annotations

import socket
import socketserver
import threading

from gyrocal.instruments.driver_spec import (
    TCP_HOST_PORT,
    DriverSpec,
    OpenRequest,
    Role,
    Setting,
    SettingKind,
    SimRequest,
)
from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentTimeout,
)
from gyrocal.instruments.interfaces import ChamberStatus, Identity
from gyrocal.instruments.retry import RetryPolicy, call_with_retry
from gyrocal.models.chamber import ChamberPhysics

FAULTS = ("no_reply", "alarm")


class DemoChamber:
    """The driver: satisfies gyrocal's ``Chamber`` interface (instruments/interfaces.py)."""

    name = "chamber (Demo TC-1)"

    def __init__(self, address: str, timeout_s: float, retries: int, on_retry=None) -> None:
        host, port = address.rsplit(":", 1)
        self.address, self._where = address, (host, int(port))
        self.timeout_s, self.on_retry = timeout_s, on_retry
        self.retry = RetryPolicy(attempts=max(1, retries))
        self._sock: socket.socket | None = None
        self._buffer = b""

    def _exchange(self, command: str) -> str:
        try:
            if self._sock is None:
                self._sock = socket.create_connection(self._where, timeout=self.timeout_s)
                self._buffer = b""
            self._sock.sendall(command.encode() + b"\n")
            while b"\n" not in self._buffer:
                chunk = self._sock.recv(256)
                if not chunk:
                    raise InstrumentConnectionError(self.name, command, "connection closed")
                self._buffer += chunk
        except TimeoutError:
            self.reset_link()
            raise InstrumentTimeout(self.name, command) from None
        except OSError as exc:
            self.reset_link()
            raise InstrumentConnectionError(self.name, command, str(exc)) from None
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line.decode().strip()

    def _ask(self, command: str) -> str:
        return call_with_retry(lambda: self._exchange(command), self.retry, self.on_retry)

    def _number(self, command: str) -> float:
        reply = self._ask(command)
        try:
            return float(reply)
        except ValueError:
            raise InstrumentError(self.name, command, "not a number", reply) from None

    def identify(self) -> Identity:
        return Identity("chamber", "demo_chamber", self.address, self._ask("ID?"))

    def read_temperature_c(self) -> float:
        return self._number("TEMP?")

    def read_setpoint_c(self) -> float:
        return self._number("SETP?")

    def set_setpoint_c(self, setpoint_c: float) -> None:
        reply = self._ask(f"SETP {setpoint_c:.2f}")
        if reply != "OK":
            raise InstrumentError(self.name, f"SETP {setpoint_c:.2f}", "refused", reply)

    def read_status(self) -> ChamberStatus:
        alarm = self._ask("ALARM?") == "1"
        return ChamberStatus(self.read_temperature_c(), self.read_setpoint_c(), alarm,
                             "alarm" if alarm else "")

    def reset_link(self) -> None:
        if self._sock is not None:
            self._sock.close()
        self._sock, self._buffer = None, b""

    def close(self) -> None:
        self.reset_link()


class SimulatedDemoChamber:
    """Its simulator: a real TCP server on loopback answering from gyrocal's chamber physics."""

    def __init__(self, physics: ChamberPhysics, faults) -> None:
        self.physics, self.faults = physics, faults
        self._server: socketserver.ThreadingTCPServer | None = None

    @property
    def address(self) -> str:
        assert self._server is not None, "start() first"
        return f"127.0.0.1:{self._server.server_address[1]}"

    def answer(self, line: str) -> str | None:
        if self.faults.take("no_reply") is not None:
            return None
        if line == "ID?":
            return "Demo Chambers,TC-1,DEMO-0001"
        if line == "TEMP?":
            return f"{self.physics.temperature_c():.3f}"
        if line == "SETP?":
            return f"{self.physics.setpoint_c:.3f}"
        if line == "ALARM?":
            return "1" if self.faults.is_armed("alarm") else "0"
        if line.startswith("SETP "):
            self.physics.set_setpoint(float(line[5:]))
            return "OK"
        return "ERR"

    def start(self) -> SimulatedDemoChamber:
        sim = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                for raw in self.rfile:
                    reply = sim.answer(raw.decode().strip())
                    if reply is not None:
                        self.wfile.write(reply.encode() + b"\n")

        socketserver.ThreadingTCPServer.allow_reuse_address = True
        self._server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Handler)
        self._server.daemon_threads = True
        threading.Thread(target=self._server.serve_forever, daemon=True).start()
        return self

    def stop(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()


def _open(req: OpenRequest) -> DemoChamber:
    return DemoChamber(req.address, req.timeout_s, req.retries, req.on_retry)


def _simulate(req: SimRequest) -> SimulatedDemoChamber:
    assert req.chamber is not None
    return SimulatedDemoChamber(req.chamber, req.faults)


SPEC = DriverSpec(
    name="demo_chamber", role=Role.CHAMBER,
    summary="Demo Chambers TC-1, plain text over TCP (a plug-in example)",
    address=TCP_HOST_PORT, open=_open,
    settings=(Setting("zone", SettingKind.INTEGER, 1, minimum=1, maximum=4,
                      doc="control zone (the demo has one; shows a plug-in's own setting)"),),
    simulator=_simulate, sim_faults=FAULTS,
    documents=("this file's docstring (an imaginary controller)",))
