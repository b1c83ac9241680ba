"""A byte-for-byte TCP proxy that can act between a request and its reply.

Used to put a signal *inside* an instrument exchange: the controller has sent
its request and waits for the reply, the proxy has the reply in hand and
holds it back while ``on_request`` runs (for instance ``os.kill(pid, SIGINT)``),
then forwards it. Nothing of gyrocal is used here: the proxy only counts the
chunks the client sends (one Modbus request or one table command line each,
since the controller writes a request in one ``send``).
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable


class ExchangeProxy:
    """Listen on 127.0.0.1; forward each accepted connection to ``target`` (host, port)."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        self.requests = 0
        self.trigger_at: int | None = None
        self.on_request: Callable[[], None] | None = None
        self.hold_reply_s = 0.2
        self.fired_at_request: int | None = None
        self._lock = threading.Lock()
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self._closed = threading.Event()
        threading.Thread(target=self._accept, daemon=True).start()

    def arm(self, at_request: int, action: Callable[[], None]) -> None:
        """Run ``action`` when request number ``at_request`` (counted from now) has been forwarded."""
        with self._lock:
            self.requests = 0
            self.trigger_at = at_request
            self.on_request = action
            self.fired_at_request = None

    def close(self) -> None:
        self._closed.set()
        self._server.close()

    def _accept(self) -> None:
        while not self._closed.is_set():
            try:
                client, _ = self._server.accept()
            except OSError:
                return
            upstream = socket.create_connection(self.target)
            pending = threading.Event()     # set while a triggered request awaits its reply
            threading.Thread(target=self._client_to_server, args=(client, upstream, pending),
                             daemon=True).start()
            threading.Thread(target=self._server_to_client, args=(upstream, client, pending),
                             daemon=True).start()

    def _client_to_server(self, client: socket.socket, upstream: socket.socket,
                          pending: threading.Event) -> None:
        try:
            while data := client.recv(65536):
                with self._lock:
                    self.requests += 1
                    fire = self.trigger_at is not None and self.requests == self.trigger_at
                    if fire:
                        self.trigger_at = None
                        self.fired_at_request = self.requests
                        pending.set()
                upstream.sendall(data)
        except OSError:
            pass
        finally:
            _close(upstream)

    def _server_to_client(self, upstream: socket.socket, client: socket.socket,
                          pending: threading.Event) -> None:
        try:
            while data := upstream.recv(65536):
                if pending.is_set():
                    # the reply is here and the client is still waiting for it: act now
                    pending.clear()
                    if self.on_request is not None:
                        self.on_request()
                    time.sleep(self.hold_reply_s)
                client.sendall(data)
        except OSError:
            pass
        finally:
            _close(client)


def _close(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)
    sock.close()
