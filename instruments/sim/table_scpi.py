"""The simulated ACUTROL3000's command interpreter: SCPI text in, replies and errors out.

Kept apart from the socket server so the instrument's *language* (headers,
abbreviations, arguments, the error queue) is one piece and the transport and
injected faults another. The interpreter answers from :class:`TablePhysics`
at the clock's now.

Accepted headers (case-insensitive; each node in long, SCPI short or the
single-letter ACUTROL form, e.g. ``:DEMAND:RATE``, ``:DEM:RAT``, ``:D:R``)::

    *IDN?                          identity
    *CLS                           clear the error queue
    :MODE:RATE <axis>              enter rate mode (refused while the interlock is open)
    :MODE:OFF <axis>               servo to rest (always accepted)
    :MODE? <axis>                  RATE | OFF
    :DEMAND:RATE <axis>, <deg/s>   rate demand (rate mode only, within the rate limit)
    :DEMAND:RATE? <axis>           current demand
    :READ:RATE? <axis>             rate readback, deg/s
    :READ:POS? <axis>              position readback, deg in [0, 360)
    :INTERLOCK? <axis>             1 closed, 0 open
    :INTERLOCK:CLOSE <axis>        close the interlock (refused while the safety chain is open)
    :INTERLOCK:OPEN <axis>         open it (the table stops)
    :LIMIT:ACC RATE, <axis>, <deg/s^2>   acceleration limit of rate mode
    :LIMIT:ACC? RATE, <axis>
    :SYSTEM:ERROR?                 oldest queued error: <code>,"<message>" (0,"No error")
    :INTERLOCK:RESET <axis>        clear latched interlock faults
    :UTILITY:LOCKOUT ON|OFF        remote lockout of the front panel

Two reply dialects (``acutrol_protocol.Dialect``): SCPI error queue (above:
settings silent, queries joined with ``;``) and the acknowledged one of the
public script for a real ACUTROL (every line answered: ``OK``, the value, or
``ERROR <code>,"<message>"``, after an 8-character prefix) — see
:meth:`AcutrolInterpreter.execute_acknowledged`. An unknown command is never
met with silence in the acknowledged dialect.

Several commands may share one line separated by ``;``; the replies of the
queries among them are joined with ``;`` in order. A query that fails queues
an error and contributes no reply (SCPI behaviour).

The acceleration-limit syntax ``:limit:acc <mode>,<axis>,<value>`` follows a
public user script that drives a real ACUTROL3000 through pyvisa; the error
codes below are SCPI-standard except the device-specific ``201`` (interlock
open), which is an assumption of this simulator (no manual was available).
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from gyrocal.models.table import (
    MODE_RATE,
    TableInterlockError,
    TableLimitError,
    TableModeError,
    TablePhysics,
)

#: SCPI error codes the simulator queues, with their standard messages.
ERR_NONE = (0, "No error")
ERR_DATA_TYPE = (-104, "Data type error")
ERR_PARAM_NOT_ALLOWED = (-108, "Parameter not allowed")
ERR_MISSING_PARAM = (-109, "Missing parameter")
ERR_UNDEFINED_HEADER = (-113, "Undefined header")
ERR_EXECUTION = (-200, "Execution error")
ERR_SETTINGS_CONFLICT = (-221, "Settings conflict")
ERR_OUT_OF_RANGE = (-222, "Data out of range")
ERR_ILLEGAL_VALUE = (-224, "Illegal parameter value")
ERR_QUEUE_OVERFLOW = (-350, "Queue overflow")
ERR_INTERLOCK_OPEN = (201, "Interlock open")

_ERROR_QUEUE_LENGTH = 16

_ROOT_NODES = {
    "MODE": ("M", "MOD", "MODE"),
    "DEMAND": ("D", "DEM", "DEMAND"),
    "READ": ("R", "READ"),
    "INTERLOCK": ("I", "INT", "INTERLOCK"),
    "LIMIT": ("L", "LIM", "LIMIT"),
    "SYSTEM": ("SYST", "SYSTEM"),
    "UTILITY": ("U", "UTIL", "UTILITY"),
}
_LEAF_NODES = {
    "RATE": ("R", "RAT", "RATE"),
    "POSITION": ("P", "POS", "POSITION"),
    "OFF": ("O", "OFF"),
    "CLOSE": ("C", "CLOS", "CLOSE"),
    "OPEN": ("OPEN",),
    "ACCELERATION": ("A", "ACC", "ACCELERATION"),
    "ERROR": ("ERR", "ERROR"),
    "RESET": ("RES", "RESET"),
    "LOCKOUT": ("LOCK", "LOCKOUT"),
}
_ROOT_ALIASES = {alias: name for name, aliases in _ROOT_NODES.items() for alias in aliases}
_LEAF_ALIASES = {alias: name for name, aliases in _LEAF_NODES.items() for alias in aliases}


@dataclass(frozen=True)
class ScpiCommand:
    """One command of a line: canonical header path, query flag, raw arguments."""

    text: str
    path: tuple[str, ...] | None  # None: the header is not in the command set
    query: bool
    args: tuple[str, ...]

    @property
    def is_setting(self) -> bool:
        return not self.query


class CommandFailed(Exception):
    """Raised inside a handler: the command is refused with this SCPI error."""

    def __init__(self, error: tuple[int, str], detail: str = "") -> None:
        super().__init__(detail)
        self.error = error
        self.detail = detail


def parse_command(text: str) -> ScpiCommand:
    """Split ``:DEM:RATE 1, 20`` into its canonical path, query flag and arguments."""
    text = text.strip()
    header, _, arg_text = text.replace("\t", " ").partition(" ")
    args = tuple(a.strip() for a in arg_text.split(",")) if arg_text.strip() else ()
    header = header.upper()
    query = header.endswith("?")
    header = header.rstrip("?")
    if header.startswith("*"):
        return ScpiCommand(text, (header,), query, args)
    nodes = [n for n in header.split(":") if n]
    path: tuple[str, ...] | None = None
    if header.startswith(":") and 1 <= len(nodes) <= 2:
        root = _ROOT_ALIASES.get(nodes[0])
        leaf = _LEAF_ALIASES.get(nodes[1]) if len(nodes) == 2 else None
        if root is not None and (len(nodes) == 1 or leaf is not None):
            path = (root,) if leaf is None else (root, leaf)
    if path is not None and path[0] == "READ":
        query = True  # ACUTROL answers :R:R 1 with or without the "?"
    return ScpiCommand(text, path, query, args)


def parse_line(line: str) -> list[ScpiCommand]:
    return [parse_command(part) for part in line.split(";") if part.strip()]


def format_error(error: tuple[int, str], detail: str = "") -> str:
    """SCPI error text: ASCII only (the protocol's character set), no embedded quotes."""
    code, message = error
    text = f"{message};{detail}" if detail else message
    text = text.replace('"', "'").encode("ascii", "replace").decode("ascii")
    return f'{code},"{text}"'


class AcutrolInterpreter:
    """Executes parsed commands against the physics and keeps the SCPI error queue."""

    def __init__(self, physics: TablePhysics, idn: str, axes: tuple[int, ...] = (1,)) -> None:
        self.physics = physics
        self.idn = idn
        self.axes = axes
        #: True while the (simulated) safety chain is broken: the interlock cannot close.
        self.safety_chain_open = False
        self._errors: deque[str] = deque()
        self._lock = threading.Lock()
        self._handlers: dict[tuple[tuple[str, ...], bool], Callable[[ScpiCommand], str | None]] = {
            (("*IDN",), True): lambda c: self._no_args(c) or self.idn,
            (("*CLS",), False): self._clear_errors,
            (("MODE", "RATE"), False): self._mode_rate,
            (("MODE", "OFF"), False): self._mode_off,
            (("MODE",), True): self._mode_query,
            (("DEMAND", "RATE"), False): self._demand_rate,
            (("DEMAND", "RATE"), True): self._demand_rate_query,
            (("READ", "RATE"), True): self._read_rate,
            (("READ", "POSITION"), True): self._read_position,
            (("INTERLOCK",), True): self._interlock_query,
            (("INTERLOCK", "CLOSE"), False): self._interlock_close,
            (("INTERLOCK", "OPEN"), False): self._interlock_open,
            (("LIMIT", "ACCELERATION"), False): self._limit_acc,
            (("LIMIT", "ACCELERATION"), True): self._limit_acc_query,
            (("SYSTEM", "ERROR"), True): self._pop_error,
            (("INTERLOCK", "RESET"), False): self._interlock_reset,
            (("UTILITY", "LOCKOUT"), False): self._lockout,
        }
        self.remote_lockout = False

    # ----- error queue --------------------------------------------------------------------

    def push_error(self, error: tuple[int, str], detail: str = "") -> None:
        with self._lock:
            if len(self._errors) >= _ERROR_QUEUE_LENGTH:
                self._errors[-1] = format_error(ERR_QUEUE_OVERFLOW)
            else:
                self._errors.append(format_error(error, detail))

    def pending_errors(self) -> list[str]:
        with self._lock:
            return list(self._errors)

    # ----- execution ----------------------------------------------------------------------

    def execute(self, command: ScpiCommand) -> str | None:
        """Run one command; its reply text, or None (setting, or a query that failed)."""
        handler = self._handlers.get((command.path, command.query)) if command.path else None
        if handler is None:
            self.push_error(ERR_UNDEFINED_HEADER, command.text)
            return None
        try:
            return handler(command)
        except CommandFailed as exc:
            self.push_error(exc.error, exc.detail)
            return None

    def execute_acknowledged(self, command: ScpiCommand) -> str:
        """The acknowledged dialect: every command answered — OK, its value, or ERROR."""
        handler = self._handlers.get((command.path, command.query)) if command.path else None
        if handler is None:
            return f"ERROR {format_error(ERR_UNDEFINED_HEADER, command.text)}"
        try:
            reply = handler(command)
        except CommandFailed as exc:
            return f"ERROR {format_error(exc.error, exc.detail)}"
        return "OK" if reply is None else reply

    def execute_line(self, commands: list[ScpiCommand]) -> str | None:
        """Run the commands of one line; the joined query replies, or None if there are none."""
        replies = [r for r in (self.execute(c) for c in commands) if r is not None]
        return ";".join(replies) if replies else None

    # ----- argument helpers ---------------------------------------------------------------

    @staticmethod
    def _no_args(command: ScpiCommand) -> None:
        if command.args:
            raise CommandFailed(ERR_PARAM_NOT_ALLOWED, command.text)

    @staticmethod
    def _arity(command: ScpiCommand, count: int) -> tuple[str, ...]:
        if len(command.args) < count or any(not a for a in command.args):
            raise CommandFailed(ERR_MISSING_PARAM, command.text)
        if len(command.args) > count:
            raise CommandFailed(ERR_PARAM_NOT_ALLOWED, command.text)
        return command.args

    @staticmethod
    def _number(text: str, command: ScpiCommand) -> float:
        try:
            value = float(text)
        except ValueError:
            raise CommandFailed(ERR_DATA_TYPE, command.text) from None
        if not math.isfinite(value):
            raise CommandFailed(ERR_DATA_TYPE, command.text)
        return value

    def _axis(self, text: str, command: ScpiCommand) -> int:
        value = self._number(text, command)
        if value != int(value) or int(value) not in self.axes:
            raise CommandFailed(ERR_OUT_OF_RANGE, f"axis {text}")
        return int(value)

    def _refusing(self, action: Callable[[], None]) -> None:
        """Turn the physics' refusals into the matching SCPI errors."""
        try:
            action()
        except TableInterlockError as exc:
            raise CommandFailed(ERR_INTERLOCK_OPEN, str(exc)) from None
        except TableLimitError as exc:
            raise CommandFailed(ERR_OUT_OF_RANGE, str(exc)) from None
        except TableModeError as exc:
            raise CommandFailed(ERR_SETTINGS_CONFLICT, str(exc)) from None

    # ----- handlers -----------------------------------------------------------------------

    def _clear_errors(self, command: ScpiCommand) -> None:
        self._no_args(command)
        with self._lock:
            self._errors.clear()

    def _pop_error(self, command: ScpiCommand) -> str:
        self._no_args(command)
        with self._lock:
            return self._errors.popleft() if self._errors else format_error(ERR_NONE)

    def _mode_rate(self, command: ScpiCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self._refusing(self.physics.set_mode_rate)

    def _mode_off(self, command: ScpiCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self.physics.set_mode_off()

    def _mode_query(self, command: ScpiCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return "RATE" if self.physics.mode == MODE_RATE else "OFF"

    def _demand_rate(self, command: ScpiCommand) -> None:
        axis_text, rate_text = self._arity(command, 2)
        self._axis(axis_text, command)
        rate_dps = self._number(rate_text, command)
        self._refusing(lambda: self.physics.set_rate_demand_dps(rate_dps))

    def _demand_rate_query(self, command: ScpiCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.demand_dps:.6f}"

    def _read_rate(self, command: ScpiCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.read_rate_dps():.6f}"

    def _read_position(self, command: ScpiCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.position_deg():.6f}"

    def _interlock_query(self, command: ScpiCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return "1" if self.physics.interlock_closed else "0"

    def _interlock_close(self, command: ScpiCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        if self.safety_chain_open:
            raise CommandFailed(ERR_INTERLOCK_OPEN, "safety chain open, interlock cannot close")
        self.physics.close_interlock()

    def _interlock_open(self, command: ScpiCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self.physics.open_interlock()

    def _interlock_reset(self, command: ScpiCommand) -> None:
        self._axis(*self._arity(command, 1), command)   # clears latched faults: nothing latched here

    def _lockout(self, command: ScpiCommand) -> None:
        (state,) = self._arity(command, 1)
        if state.upper() not in ("ON", "OFF"):
            raise CommandFailed(ERR_ILLEGAL_VALUE, f"lockout {state!r}")
        self.remote_lockout = state.upper() == "ON"

    def _limit_mode(self, text: str) -> None:
        if text.upper() not in ("RATE", "RAT", "R"):
            raise CommandFailed(ERR_ILLEGAL_VALUE, f"limit mode {text!r} (only RATE simulated)")

    def _limit_acc(self, command: ScpiCommand) -> None:
        mode_text, axis_text, accel_text = self._arity(command, 3)
        self._limit_mode(mode_text)
        self._axis(axis_text, command)
        accel_dps2 = self._number(accel_text, command)
        self._refusing(lambda: self.physics.set_accel_limit_dps2(accel_dps2))

    def _limit_acc_query(self, command: ScpiCommand) -> str:
        mode_text, axis_text = self._arity(command, 2)
        self._limit_mode(mode_text)
        self._axis(axis_text, command)
        return f"{self.physics.accel_limit_dps2:.6f}"
