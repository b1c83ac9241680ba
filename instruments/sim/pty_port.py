"""The pseudo-terminal and writer-thread plumbing shared by the simulated serial gyros.

The simulated STIM300 (gyro_pty.py) and the capture replay (replay_pty.py) differ
in what they write, not in how a port is opened, started, stopped and closed:
one owner for that keeps both safe to stop twice and unable to restart after stop.
"""

from __future__ import annotations

import contextlib
import os
import threading
import tty
from typing import TypeVar

_P = TypeVar("_P", bound="PtyWriterPort")


class PtyWriterPort:
    """A raw pty whose master a writer thread (:meth:`_run`) feeds; the driver opens
    :attr:`port_name` exactly as it would a real serial device."""

    #: the writer thread's name, and how errors name the port
    thread_name = "pty-writer"
    label = "pty port"

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._master_fd, self._slave_fd = os.openpty()
        tty.setraw(self._slave_fd)
        os.set_blocking(self._master_fd, False)
        self.port_name = os.ttyname(self._slave_fd)
        self._closed = False

    def _run(self) -> None:
        raise NotImplementedError

    def _before_start(self) -> None:
        """Hook: runs once, just before the writer thread starts."""

    def _before_join(self) -> None:
        """Hook: runs on stop(), after the stop flag is set and before the thread is joined."""

    def start(self: _P) -> _P:
        if self._closed:
            raise RuntimeError(f"{self.label}: cannot start after stop()")
        if self._thread is None:
            self._before_start()
            self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the writer, join it and close both pty ends (safe to call twice)."""
        self._stop.set()
        self._before_join()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if not self._closed:
            self._closed = True
            for fd in (self._master_fd, self._slave_fd):
                with contextlib.suppress(OSError):
                    os.close(fd)

    @property
    def running(self) -> bool:
        """True while the writer thread is alive (it ends on stop() or on an error)."""
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self: _P) -> _P:
        return self.start()

    def __exit__(self, *exc_info) -> None:
        self.stop()
