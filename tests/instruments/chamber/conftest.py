"""Fixtures for the chamber driver tests: simulated chambers on loopback and a scripted peer."""

from __future__ import annotations

import socket
import threading

import pytest

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4
from gyrocal.instruments.chamber.watlow_f4t import WatlowF4T
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.sim.chamber_server import SimulatedWatlowF4, SimulatedWatlowF4T
from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import SimClock

FAST_RETRY = RetryPolicy(attempts=3, backoff_s=0.01, backoff_factor=1.0)
TIMEOUT_S = 0.25


@pytest.fixture
def clock():
    return SimClock()


@pytest.fixture
def physics(clock):
    return ChamberPhysics(clock, ambient_c=22.0, tau_s=300.0, noise_c=0.0, seed=5)


MODELS = {
    "f4": (SimulatedWatlowF4, WatlowF4),
    "f4t": (SimulatedWatlowF4T, WatlowF4T),
}


@pytest.fixture(params=sorted(MODELS))
def rig(request, physics):
    """(simulator, driver, retries seen) for each chamber model."""
    sim_cls, driver_cls = MODELS[request.param]
    retries = []
    with sim_cls(physics) as sim:
        # an F4's alarm is the limit controller's digital input, declared per station
        extra = {"limit_input": 1} if request.param == "f4" else {}
        driver = driver_cls(
            sim.address, timeout_s=TIMEOUT_S, retry=FAST_RETRY,
            on_retry=lambda attempt, exc: retries.append(exc), **extra,
        )
        try:
            yield sim, driver, retries
        finally:
            driver.close()


class ScriptedPeer:
    """A loopback TCP server that expects exact request bytes and answers exact reply bytes.

    The PyMeasure style of protocol test, over a real socket: the byte pairs
    come from the manual (or are worked by hand), so the test pins the driver's
    framing, addresses and encodings rather than echoing its own code.
    """

    def __init__(self, pairs: list[tuple[bytes, bytes]]) -> None:
        self.pairs = list(pairs)
        self.received: list[bytes] = []
        self.error: str | None = None
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._listener.settimeout(5.0)
        self.port = self._listener.getsockname()[1]
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        try:
            conn, _ = self._listener.accept()
        except OSError as exc:
            self.error = f"no connection: {exc}"
            return
        with conn:
            conn.settimeout(5.0)
            for expected, reply in self.pairs:
                got = b""
                while len(got) < len(expected):
                    chunk = conn.recv(len(expected) - len(got))
                    if not chunk:
                        self.error = f"peer closed after {got.hex(' ')}"
                        return
                    got += chunk
                self.received.append(got)
                if got != expected:
                    self.error = f"expected {expected.hex(' ')}, got {got.hex(' ')}"
                    return
                conn.sendall(reply)

    def close(self) -> None:
        self._listener.close()
        self._thread.join(5.0)


@pytest.fixture
def scripted_peer():
    peers = []

    def make(pairs):
        peer = ScriptedPeer([(bytes.fromhex(req), bytes.fromhex(rep)) for req, rep in pairs])
        peers.append(peer)
        return peer

    yield make
    for peer in peers:
        peer.close()
