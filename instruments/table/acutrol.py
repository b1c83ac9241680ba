"""ACUTROL3000 rate-table driver over VISA sockets (pyvisa with the pyvisa-py backend).

The orchestrator leaves a table spinning unattended overnight, so the driver
must never be left in doubt about what the table did:

- the reply dialect is declared (``acutrol_protocol.Dialect``): by default the
  one of the public script that drives a real ACUTROL (every line answered,
  ``OK`` for a setting, an 8-character prefix before each reply, CR LF, remote
  lockout and an interlock open/reset/close at session start); the SCPI
  error-queue form (settings silent, ``:syst:err?`` on the same line) is the
  named alternative ``scpi-error-queue``. Either way a refused setting is an
  error at once, at one round trip;
- after any transport fault (timeout, reset, garbled reply) the session is
  discarded and the next attempt opens a fresh one, because a reply arriving
  late on the old socket would otherwise be read as the answer to the *next*
  question; reconnecting is therefore how retries recover a dropped link;
- a refusal because the interlock is open is an :class:`InstrumentSafetyError`
  (the orchestrator must go to the safe state), other refusals an
  :class:`InstrumentProtocolError`; both name the table, the command and the reply.

The session opens lazily on the first command, so building the driver never
blocks and every connection attempt goes through the retry policy.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import pyvisa
from pyvisa import constants as visa_constants
from pyvisa import rname
from pyvisa.errors import VisaIOError

from gyrocal.instruments.errors import (
    InstrumentConnectionError,
    InstrumentError,
    InstrumentProtocolError,
    InstrumentSafetyError,
    InstrumentTimeout,
)
from gyrocal.instruments.interfaces import Identity, TableStatus
from gyrocal.instruments.retry import RetryPolicy, call_with_retry
from gyrocal.instruments.table import acutrol_protocol as proto

T = TypeVar("T")

DRIVER_NAME = "acutrol3000"


class Acutrol3000Table:
    """One axis of an ACUTROL3000-controlled rate table (the ``RateTable`` role)."""

    def __init__(
        self,
        resource: str,
        axis: int = 1,
        timeout_s: float = 2.0,
        retry: RetryPolicy | None = None,
        name: str = "table",
        on_retry: Callable[[int, InstrumentError], None] | None = None,
        dialect: str = proto.DEFAULT_DIALECT,
    ) -> None:
        if dialect not in proto.DIALECTS:
            raise ValueError(f"{name}: dialect must be one of {sorted(proto.DIALECTS)}, got {dialect!r}")
        self.dialect = proto.DIALECTS[dialect]
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"{name}: timeout_s must be a finite number > 0, got {timeout_s!r}")
        if int(axis) != axis or axis < 1:
            raise ValueError(f"{name}: axis must be a positive integer, got {axis!r}")
        _check_resource(resource, name)
        self.resource = resource
        self.axis = int(axis)
        self.timeout_s = float(timeout_s)
        self.retry = retry if retry is not None else RetryPolicy()
        self.name = name
        self.on_retry = on_retry
        self._session: Any = None
        self._started = False          # the dialect's start-up list has run once
        self._lock = threading.RLock()
        self._closed = False

    # ----- RateTable ----------------------------------------------------------------------

    def identify(self) -> Identity:
        description = self._query(proto.IDENTIFY)
        return Identity("table", DRIVER_NAME, self.resource, description)

    def interlock_closed(self) -> bool:
        return self._query(proto.INTERLOCK_QUERY)

    def close_interlock(self) -> None:
        self._setting(proto.INTERLOCK_CLOSE)

    def set_rate_mode(self) -> None:
        self._setting(proto.MODE_RATE)

    def set_acceleration_limit_dps2(self, accel_dps2: float) -> None:
        self._setting(proto.LIMIT_ACCELERATION, accel_dps2=self._finite(accel_dps2, "accel"))

    def read_acceleration_limit_dps2(self) -> float:
        return self._query(proto.LIMIT_ACCELERATION_QUERY)

    def set_rate_dps(self, rate_dps: float) -> None:
        self._setting(proto.DEMAND_RATE, rate_dps=self._finite(rate_dps, "rate"))

    def read_rate_dps(self) -> float:
        return self._query(self.dialect.read_rate)

    def read_position_deg(self) -> float:
        return self._query(self.dialect.read_position)

    def read_status(self) -> TableStatus:
        if self.dialect.acknowledged:        # one reply per line: three questions
            return TableStatus(rate_dps=self.read_rate_dps(), position_deg=self.read_position_deg(),
                               interlock_closed=self.interlock_closed())
        rate_dps, position_deg, closed = self._query(proto.STATUS_QUERY)
        return TableStatus(rate_dps=rate_dps, position_deg=position_deg, interlock_closed=closed)

    def stop(self) -> None:
        """Demand zero, then servo off; servo-off is attempted even if the demand was refused.

        A refused zero demand is expected when the table is already off or its
        interlock is open (it is then stopping by itself), so only a failure of
        ``:mode:off`` — the safe state itself — is raised.
        """
        with self._lock:
            with contextlib.suppress(InstrumentError):
                self._setting(proto.DEMAND_RATE, rate_dps=0.0)
            self._setting(proto.MODE_OFF)

    def reset_link(self) -> None:
        """Discard the session (and any late reply in it); the next command opens a fresh one."""
        with self._lock:
            self._drop_session()

    def close(self) -> None:
        """Close this table's session (never the shared pyvisa ResourceManager)."""
        with self._lock:
            self._closed = True
            self._drop_session()

    def __enter__(self) -> Acutrol3000Table:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----- transactions -------------------------------------------------------------------

    def _query(self, command: proto.Command) -> Any:
        text = command.text(axis=self.axis)
        return self._with_retry(
            text, lambda: self._parse(command.parse, text, self._answer(text))
        )

    def _answer(self, text: str) -> str:
        """The reply's value: the dialect's prefix removed; an ERROR reply refused."""
        reply = self._exchange(text)
        if not self.dialect.acknowledged:
            return reply
        value = self._parse(lambda r: proto.strip_prefix(r, self.dialect), text, reply)
        if value.upper().startswith("ERROR"):
            self._refused(text, value)
        return value

    def _refused(self, text: str, reply: str, also: str = "") -> None:
        if "interlock" in reply.lower() or " 201" in f" {reply}":
            raise InstrumentSafetyError(self.name, text, f"refused: interlock open{also}", reply=reply)
        code = proto.error_code_in(reply)
        raise InstrumentProtocolError(self.name, text, f"refused by the table{also}", reply=reply,
                                      transient=proto.refusal_may_pass(code))

    def _setting(self, command: proto.Command, **fields: Any) -> None:
        """Send a setting and raise if the table refused it (its dialect says how we know).

        A refusal is attempted again per the station's ``retries`` unless retrying cannot
        help: an SCPI command error (-100…-199: the bytes themselves are wrong) or an open
        interlock (a safety stop, never retried). The adversarial pass saw execution errors
        (the table busy finishing a move) end runs that one more attempt would have saved.
        """
        text = command.text(axis=self.axis, **fields)
        once = self._setting_acknowledged if self.dialect.acknowledged else self._setting_error_queue
        self._with_retry(text, lambda: once(text))

    def _setting_acknowledged(self, text: str) -> None:
        value = self._answer(text)
        if value.upper() != "OK":
            self._refused(text, value)

    def _setting_error_queue(self, text: str) -> None:
        """Send a setting with ``:syst:err?`` on the same line; raise if the table refused it."""
        line = f"{text};{proto.ERROR_QUERY.text()}"
        with self._lock:
            code, message = self._parse(proto.parse_error, text, self._exchange(line))
            if code == 0:
                return
            others = self._drain_errors()
        reply = f'{code},"{message}"'
        also = f" (also queued: {'; '.join(others)})" if others else ""
        if proto.is_interlock_error(code, message):
            raise InstrumentSafetyError(self.name, text, f"refused: interlock open{also}", reply=reply)
        raise InstrumentProtocolError(self.name, text, f"refused by the table{also}", reply=reply,
                                      transient=proto.refusal_may_pass(code))

    def _drain_errors(self) -> list[str]:
        """Empty the error queue so one refusal is not blamed on the next command."""
        found: list[str] = []
        for _ in range(proto.MAX_QUEUED_ERRORS):
            text = proto.ERROR_QUERY.text()
            try:
                code, message = self._parse(proto.parse_error, text, self._exchange(text))
            except InstrumentError:
                break
            if code == 0:
                break
            found.append(f'{code},"{message}"')
        return found

    def _with_retry(self, command: str, attempt: Callable[[], T]) -> T:
        with self._lock:
            if self._closed:
                raise InstrumentConnectionError(self.name, command, "driver already closed")
            return call_with_retry(attempt, self.retry, on_retry=self.on_retry)

    def _parse(self, parse: Callable[[str], T] | None, command: str, reply: str) -> T:
        assert parse is not None
        try:
            return parse(reply)
        except proto.ReplyFormatError as exc:
            self._drop_session()  # garbage may hide a terminator: resynchronise on a new socket
            raise InstrumentProtocolError(
                self.name, command, f"unreadable reply: {exc}", reply=reply, transient=True
            ) from None

    def _exchange(self, line: str) -> str:
        """Write one line and read one reply line, mapping transport faults to instrument errors."""
        session = self._open(line)
        try:
            return session.query(line)
        except VisaIOError as exc:
            self._drop_session()
            if exc.error_code == visa_constants.StatusCode.error_timeout:
                raise InstrumentTimeout(
                    self.name, line, f"no reply within {self.timeout_s:g} s"
                ) from None
            raise InstrumentConnectionError(self.name, line, f"VISA I/O error: {exc}") from None
        except OSError as exc:
            self._drop_session()
            raise InstrumentConnectionError(
                self.name, line, f"connection lost ({exc.__class__.__name__}: {exc})"
            ) from None

    def _open(self, line: str) -> Any:
        if self._session is not None:
            return self._session
        timeout_ms = max(1, round(self.timeout_s * 1000))
        try:
            manager = pyvisa.ResourceManager("@py")
            session = manager.open_resource(
                self.resource,
                open_timeout=timeout_ms,
                read_termination=self.dialect.terminator,
                write_termination=self.dialect.terminator,
                timeout=timeout_ms,
                encoding="latin-1",
            )
        except VisaIOError as exc:
            if exc.error_code == visa_constants.StatusCode.error_invalid_resource_name:
                raise InstrumentError(
                    self.name, line, f"invalid VISA resource {self.resource!r}"
                ) from None
            raise InstrumentConnectionError(
                self.name, line, f"cannot open {self.resource}: {exc}"
            ) from None
        except Exception as exc:  # pyvisa-py raises a bare Exception when connect fails
            raise InstrumentConnectionError(
                self.name, line, f"cannot open {self.resource}: {exc}"
            ) from None
        try:
            if self.dialect.acknowledged:
                self._start_session(session)
            else:
                session.write(proto.CLEAR_STATUS.text())  # a new session starts with an empty queue
        except (VisaIOError, OSError) as exc:
            _close_quietly(session)
            if (isinstance(exc, VisaIOError)
                    and exc.error_code == visa_constants.StatusCode.error_timeout):
                raise InstrumentTimeout(
                    self.name, "session start", f"no reply within {self.timeout_s:g} s"
                ) from None
            raise InstrumentConnectionError(
                self.name, "session start", f"cannot talk to {self.resource}: {exc}"
            ) from None
        self._session = session
        return session

    def _start_session(self, session: Any) -> None:
        """The dialect's start-up list (once; a reconnect runs the shorter list), each ``OK``."""
        commands = self.dialect.reconnect if self._started else self.dialect.startup
        for command in commands:
            text = command.text(axis=self.axis)
            reply = session.query(text)
            value = reply[self.dialect.reply_prefix:].strip()
            if not (reply.isascii() and reply.isprintable()):
                _close_quietly(session)         # garbage: resynchronise on a new socket
                raise InstrumentProtocolError(self.name, text, "unreadable reply at session start",
                                              reply=reply, transient=True)
            if value.upper() != "OK":
                _close_quietly(session)
                self._refused(text, reply, " at session start")
        self._started = True

    def _drop_session(self) -> None:
        session, self._session = self._session, None
        if session is not None:
            _close_quietly(session)

    def _finite(self, value: float, what: str) -> float:
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"{self.name}: {what} must be a finite number, got {value!r}")
        return value


def _check_resource(resource: str, name: str) -> None:
    """Reject a malformed resource string at construction (a station-file error, not a fault)."""
    try:
        parsed = rname.parse_resource_name(resource)
    except rname.InvalidResourceName as exc:
        raise ValueError(f"{name}: invalid VISA resource {resource!r}: {exc}") from None
    port = getattr(parsed, "port", None)
    if port is not None and not str(port).isdigit():
        raise ValueError(f"{name}: invalid VISA resource {resource!r}: port {port!r} is not a number")


def _close_quietly(session: Any) -> None:
    # Closing a dead socket must not mask the fault being reported.
    with contextlib.suppress(Exception):
        session.close()
