"""ACUTROL3000 rate-table driver over VISA sockets (pyvisa with the pyvisa-py backend).

Speaks the ACUTROL Command Language as TM-8004 defines it on the TCP/IP
interface of TM-9384C (port 9878): every command line gets one reply, an
8-byte header (error code, message length) then the message
(``acutrol_protocol``). The orchestrator leaves a table spinning unattended
overnight, so the driver must never be left in doubt about what the table did:

- a reply is framed by its length, never by guessing a terminator; the error
  code of every command is checked, so a refused setting is an error at once,
  at one round trip;
- a refusal is named with the controller's own text (``:Query:Error? <code>``)
  and classified by the documented status registers, never by the code's
  number (the manual leaves the list "TBD"): ``*STB?`` bit 0 (system
  interlocks) makes it an :class:`InstrumentSafetyError` (the orchestrator goes
  to the safe state), ``*ESR?`` bit 2 (a bad message) a refusal not worth
  repeating; any other refusal may pass on a later attempt (station ``retries``);
- after any transport fault (timeout, reset, garbled reply) the session is
  discarded and the next attempt opens a fresh one, because a reply arriving
  late on the old socket would otherwise be read as the answer to the *next*
  question; reconnecting is therefore how retries recover a dropped link;
- queries change nothing: remote lockout (``:Utility:Lockout ON``) is taken
  before the first command of a session that changes the table, so
  ``gyrocal station check`` leaves the front panel as it found it.

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
from gyrocal.instruments.visa_nodelay import no_delay

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
            raise ValueError(f"{name}: dialect must be one of {list(proto.DIALECTS)}, got {dialect!r}")
        self.dialect = dialect
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
        self._locked_out = False       # :Utility:Lockout ON sent in this session
        self._lock = threading.RLock()
        self._closed = False

    # ----- RateTable ----------------------------------------------------------------------

    def identify(self) -> Identity:
        description = self._query(proto.IDENTIFY)
        return Identity("table", DRIVER_NAME, self.resource, description)

    def interlock_state(self) -> proto.InterlockState:
        return self._query(proto.INTERLOCK_QUERY)

    def interlock_closed(self) -> bool:
        return self.interlock_state() is proto.InterlockState.CLOSE

    def close_interlock(self) -> None:
        """Unfreeze latched interlock faults (no axis: §4.5.6), then close and servo the axis."""
        self._setting(proto.INTERLOCK_RESET)
        self._setting(proto.INTERLOCK_CLOSE)

    def read_mode(self) -> proto.TableMode:
        return self._query(proto.MODE_QUERY)

    def open_interlock(self) -> None:
        """Open the interlock: the drive is unpowered and the table coasts to rest (a
        deliberate drive-off static, ``table_interference``)."""
        self._setting(proto.INTERLOCK_OPEN)

    def set_rate_mode(self) -> None:
        self._setting(proto.MODE_RATE)

    def set_position_mode(self) -> None:
        self._setting(proto.MODE_POSITION)

    def set_position_deg(self, position_deg: float) -> None:
        self._setting(proto.DEMAND_POSITION, position_deg=self._finite(position_deg, "position"))

    def set_oscillator(self, magnitude: float, frequency_hz: float, phase_deg: float) -> None:
        """The sinusoid synthesis mode will run (§4.3.4): load it before :meth:`set_synthesis_mode`."""
        if not self._finite(frequency_hz, "frequency") > 0:
            raise ValueError(f"{self.name}: frequency must be > 0 Hz, got {frequency_hz!r}")
        self._setting(proto.DEMAND_OSCILLATOR, magnitude=self._finite(magnitude, "magnitude"),
                      frequency_hz=frequency_hz, phase_deg=self._finite(phase_deg, "phase"))

    def set_synthesis_mode(self) -> None:
        """Start the sinusoid loaded by :meth:`set_oscillator`; the manual advises entering
        it from position mode, whose demand is the centre of the motion (§4.7.6)."""
        self._setting(proto.MODE_SYNTHESIS)

    def set_acceleration_limit_dps2(self, accel_dps2: float) -> None:
        self._setting(proto.LIMIT_ACCELERATION, accel_dps2=self._finite(accel_dps2, "accel"))

    def read_acceleration_limit_dps2(self) -> float:
        return self._query(proto.LIMIT_ACCELERATION_QUERY)

    def set_rate_dps(self, rate_dps: float) -> None:
        self._setting(proto.DEMAND_RATE, rate_dps=self._finite(rate_dps, "rate"))

    def read_rate_demand_dps(self) -> float:
        return self._query(proto.DEMAND_RATE_QUERY)

    def read_rate_dps(self) -> float:
        return self._query(proto.READ_RATE)

    def read_position_deg(self) -> float:
        return self._query(proto.READ_POSITION)

    def read_status(self) -> TableStatus:
        return TableStatus(rate_dps=self.read_rate_dps(), position_deg=self.read_position_deg(),
                           interlock_closed=self.interlock_closed())

    def stop(self) -> None:
        """Demand zero, then servo off; servo-off is attempted even if the demand was refused.

        A refused zero demand is expected when the table is already off or its
        interlock is open (it is then stopping by itself), so only a failure of
        ``:Mode:Off`` — the safe state itself — is raised.
        """
        with self._lock:
            with contextlib.suppress(InstrumentError):
                self._setting(proto.DEMAND_RATE, rate_dps=0.0)
            self._setting(proto.MODE_OFF)

    def hold(self) -> None:
        """Stop and keep the axis under servo: demand zero rate, then position mode.

        The safe state of a horizontal axis (``table.orientation: horizontal``):
        the servo must stay on or an unbalanced load swings the axis down.
        Position mode servos the axis to a fixed angle (TM-8004 §4.7.4,
        p. 151), which holds the angle against a gravity torque where a zero rate
        demand (§4.3.6, p. 113) would only hold the velocity. The zero demand is
        refused when the table is not in rate mode (position mode already
        holds), so only a failure of ``:Mode:Position`` — refused while the
        interlock is open — is raised.
        """
        with self._lock:
            with contextlib.suppress(InstrumentError):
                self._setting(proto.DEMAND_RATE, rate_dps=0.0)
            self._setting(proto.MODE_POSITION)

    def read_servo_mode(self) -> str:
        """The servo mode as read back (``:Mode?``, TM-8004 §4.7 p. 147): ``position``,
        ``rate``, ``arate``, ``synthesis``, ``track`` or ``off``."""
        return self.read_mode().name.lower()

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
        assert command.parse is not None
        return self._with_retry(text, lambda: self._parse(command.parse, text, self._answer(text)))

    def _setting(self, command: proto.Command, **fields: Any) -> None:
        """Send a setting; its reply's error code says whether the table took it."""
        text = command.text(axis=self.axis, **fields)

        def once() -> None:
            if not self._locked_out:
                self._answer(proto.LOCKOUT_ON.text())
                self._locked_out = True
            self._answer(text)
        self._with_retry(text, once)

    def _answer(self, text: str) -> str:
        """The message of ``text``'s reply; a nonzero error code is a refusal (raised)."""
        code, message = self._exchange(text)
        if code != 0:
            self._refused(text, code, message)
        return message

    def _refused(self, text: str, code: int, message: str) -> None:
        """Name the refusal with the controller's text and classify it by STB / ESR."""
        detail, stb, esr = self._refusal_context(code)
        reply = f"error {code}" + (f" ({detail})" if detail else "") + (f": {message}" if message else "")
        if stb & proto.STB_SYSTEM_INTERLOCKS or "interlock" in detail.lower():
            raise InstrumentSafetyError(self.name, text, "refused: interlock open", reply=reply)
        raise InstrumentProtocolError(self.name, text, "refused by the table", reply=reply,
                                      transient=not (esr & proto.ESR_BAD_MESSAGE))

    def _refusal_context(self, code: int) -> tuple[str, int, int]:
        """(error text, *STB?, *ESR?) — best effort: a failing follow-up never hides the refusal."""
        found: list[Any] = []
        for command, fields in ((proto.ERROR_TEXT, {"code": code}), (proto.STATUS_BYTE, {}),
                                (proto.EVENT_STATUS, {})):
            line = command.text(**fields)
            try:
                follow_code, message = self._exchange(line)
                assert command.parse is not None
                found.append(command.parse(message) if follow_code == 0 else None)
            except (InstrumentError, proto.ReplyFormatError):
                found.append(None)
        text, stb, esr = found
        return text or "", stb or 0, esr or 0

    def _with_retry(self, command: str, attempt: Callable[[], T]) -> T:
        with self._lock:
            if self._closed:
                raise InstrumentConnectionError(self.name, command, "driver already closed")
            return call_with_retry(attempt, self.retry, on_retry=self.on_retry)

    def _parse(self, parse: Callable[[str], T], command: str, reply: str) -> T:
        try:
            return parse(reply)
        except proto.ReplyFormatError as exc:
            raise InstrumentProtocolError(
                self.name, command, f"unreadable reply: {exc}", reply=reply, transient=True
            ) from None

    def _exchange(self, line: str) -> tuple[int, str]:
        """Write one command line, read one framed reply: (error code, message)."""
        session = self._open(line)
        raw = b""
        try:
            session.write(line)
            raw = bytes(session.read_bytes(proto.HEADER.size))
            header = proto.ReplyHeader.decode(raw)
            body = bytes(session.read_bytes(header.length)) if header.length else b""
            raw += body
            return header.error_code, proto.message_text(body)
        except proto.ReplyFormatError as exc:
            self._drop_session()  # the framing is lost: resynchronise on a new socket
            raise InstrumentProtocolError(self.name, line, f"unreadable reply: {exc}",
                                          reply=raw.decode("latin-1"), transient=True) from None
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
                self.name, line, f"connection to {self.resource} lost ({exc.__class__.__name__}: {exc})"
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
                read_termination=None,
                write_termination=proto.COMMAND_TERMINATOR,
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
        no_delay(session)      # a command line and its readback without a delayed-ACK wait
        self._session = session
        return session

    def _drop_session(self) -> None:
        session, self._session = self._session, None
        self._locked_out = False       # a new session takes the lockout again
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
