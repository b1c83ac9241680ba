"""One SCPI line link over pyvisa (pyvisa-py): open, ask, send, with the project's errors and retries.

The supply, the voltmeter and the counter are plain SCPI instruments (LF
terminated, one reply per query, errors in ``SYST:ERR?``); this is the one
place that maps their transport faults to :mod:`instruments.errors` and
retries transient ones, so each driver holds only its instrument's commands.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from typing import Any

import pyvisa
from pyvisa import constants as visa_constants
from pyvisa.errors import VisaIOError

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentProtocolError,
    InstrumentTimeout,
)
from gyrocal.instruments.retry import RetryPolicy, call_with_retry
from gyrocal.instruments.visa_nodelay import no_delay

#: SCPI error query (IEEE 488.2 / SCPI-99 SYSTem:ERRor[:NEXT]?); ``0,"No error"`` when empty
ERROR_QUERY = "SYST:ERR?"


class ScpiLink:
    """A VISA session opened on first use and dropped (then reopened) after any transport fault."""

    def __init__(self, resource: str, name: str, timeout_s: float, retry: RetryPolicy,
                 on_retry: Callable[[int, InstrumentError], None] | None = None,
                 terminator: str = "\n") -> None:
        self.resource, self.name, self.timeout_s = resource, name, float(timeout_s)
        self.retry, self.on_retry, self.terminator = retry, on_retry, terminator
        self._session: Any = None
        self._lock = threading.RLock()

    def ask(self, line: str) -> str:
        """One query, its reply line (retried on a transient fault)."""
        return self._retry(line, lambda: self._query(line))

    def ask_float(self, line: str) -> float:
        def once() -> float:
            reply = self._query(line)
            try:
                return float(reply.split(",")[0])
            except ValueError:
                self.reset()
                raise InstrumentProtocolError(self.name, line, "not a number", reply=reply,
                                              transient=True) from None
        return self._retry(line, once)

    def send(self, line: str) -> None:
        """A setting, then ``SYST:ERR?``: a refusal is raised with the code the queue holds."""
        def once() -> None:
            self._write(line)
            reply = self._query(ERROR_QUERY)
            code = reply.split(",", 1)[0].strip()
            if code not in ("0", "+0"):
                raise InstrumentProtocolError(self.name, line, "refused", reply=reply)
        self._retry(line, once)

    def reset(self) -> None:
        with self._lock:
            session, self._session = self._session, None
            if session is not None:
                with contextlib.suppress(Exception):
                    session.close()

    close = reset

    def _retry(self, line: str, attempt: Callable[[], Any]) -> Any:
        with self._lock:
            return call_with_retry(attempt, self.retry, on_retry=self.on_retry)

    def _query(self, line: str) -> str:
        session = self._open(line)
        try:
            return str(session.query(line)).strip()
        except VisaIOError as exc:
            self.reset()
            if exc.error_code == visa_constants.StatusCode.error_timeout:
                raise InstrumentTimeout(self.name, line,
                                        f"no reply within {self.timeout_s:g} s") from None
            raise InstrumentConnectionError(self.name, line, f"VISA I/O error: {exc}") from None
        except OSError as exc:
            self.reset()
            raise InstrumentConnectionError(self.name, line, f"connection lost ({exc})") from None

    def _write(self, line: str) -> None:
        session = self._open(line)
        try:
            session.write(line)
        except (VisaIOError, OSError) as exc:
            self.reset()
            raise InstrumentConnectionError(self.name, line, f"connection lost ({exc})") from None

    def _open(self, line: str) -> Any:
        if self._session is not None:
            return self._session
        timeout_ms = max(1, round(self.timeout_s * 1000))
        try:
            self._session = pyvisa.ResourceManager("@py").open_resource(
                self.resource, open_timeout=timeout_ms, timeout=timeout_ms,
                read_termination=self.terminator, write_termination=self.terminator,
                encoding="latin-1")
        except Exception as exc:  # pyvisa-py raises a bare Exception when connect fails
            raise InstrumentConnectionError(self.name, line,
                                            f"cannot open {self.resource}: {exc}") from None
        no_delay(self._session)      # a setting and its SYST:ERR? without a delayed-ACK wait
        return self._session
