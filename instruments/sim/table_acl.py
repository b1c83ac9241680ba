"""The simulated ACUTROL3000's command interpreter: ACL text in, (error code, message) out.

Kept apart from the socket server so the instrument's *language* (headers,
abbreviations, arguments, error codes, status registers) is one piece and the
transport and injected faults another. The interpreter answers from
:class:`TablePhysics` at the clock's now. It follows TM-8004-C (sections as
cited in ``instruments/table/acutrol_protocol.py``); headers are accepted
case-insensitively in the manual's long form, its short form and the
single-letter form of its examples (``:Demand:Rate``, ``:DEM:RATE``, ``:D:R``)::

    *IDN?  *CLS  *ESR?  *STB?          identity, clear status, event status, status byte
    :Mode? <axis>                      the mode letter: R rate, P position, S synthesis, O off
    :Mode:Rate <axis>                  rate mode (refused while the interlock is open)
    :Mode:Off <axis>                   servo to rest (always accepted)
    :Mode:Synthesis <axis>             the loaded oscillator's sinusoid (§4.7.6), from rest
    :Mode:Position <axis>              position mode: the indexing head (refused while the
                                       interlock is open)
    :Demand:Rate <axis>,<deg/s>        rate demand (rate mode only, within the rate limit)
    :Demand:Rate? <axis>               current demand
    :Demand:Position <axis>,<deg>      stored; in position mode the table moves there at its
                                       rate and acceleration limits (from rest)
    :Demand:Oscillator <axis>,<mag>,<Hz>,<deg>   peak position (deg), frequency, initial phase
    :Demand:Oscillator? <axis>         the loaded oscillator, ``;``-separated (§4.3.4)
    :Read:Rate[?] <axis>               rate readback, deg/s ("?" optional, §4.10.5); follows
                                       the sinusoid in synthesis mode, as does the position
    :Read:Position[?] <axis>           position readback, deg in [0, 360)
    :Interlock? <axis>                 Close | Open | Fault
    :Interlock:Close <axis>            close (refused while the safety chain is open)
    :Interlock:Open <axis>             open it (the table stops)
    :Interlock:Reset                   no argument (§4.5.6); with one it is refused
    :Limit:Acceleration R,<axis>,<deg/s^2>   acceleration limit of rate mode (§4.6.2)
    :Limit:Acceleration? R,<axis>
    :Query:Error? <code>               the text of an error code
    :Utility:Lockout ON|OFF            remote lockout of the other interfaces

Several commands may share one line separated by ``;``; the messages of the
queries among them are joined with ``;`` in order, and the line's error code
is the first command's that failed.

The error codes are this simulator's own: TM-8004 leaves its list "TBD"
(§6.1, p. 213), and the driver never reads meaning into a number. What the
driver relies on is documented: ``*STB?`` bit 0 while the system interlocks
are faulted, ``*ESR?`` bit 2 for a bad device-dependent message (axis out of
range, data of the wrong size or kind).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

from gyrocal.instruments.table import acutrol_protocol as proto
from gyrocal.models.table import (
    MODE_POSITION,
    MODE_RATE,
    MODE_SYNTHESIS,
    TableInterlockError,
    TableLimitError,
    TableModeError,
    TablePhysics,
)

#: (code, text) of the simulator's refusals; 0 is success.
ERR_UNDEFINED_HEADER = (1, "Undefined header")
ERR_BAD_PARAMETER = (2, "Parameter out of range")
ERR_INTERLOCK_OPEN = (3, "Interlock open")
ERR_SETTINGS_CONFLICT = (4, "Settings conflict")
ERR_EXECUTION = (5, "Execution error")
ERR_NOT_SIMULATED = (6, "Not simulated")
ERROR_TEXTS = dict((ERR_UNDEFINED_HEADER, ERR_BAD_PARAMETER, ERR_INTERLOCK_OPEN,
                    ERR_SETTINGS_CONFLICT, ERR_EXECUTION, ERR_NOT_SIMULATED))

_RATE = ("R", "RAT", "RATE")
_POSITION = ("P", "POS", "POSITION")
_NODES: dict[str, tuple[tuple[str, ...], dict[str, tuple[str, ...]]]] = {
    "MODE": (("M", "MOD", "MODE"), {"RATE": _RATE, "OFF": ("O", "OFF"), "POSITION": _POSITION,
                                    "SYNTHESIS": ("S", "SYNT", "SYNTH", "SYNTHESIS")}),
    "DEMAND": (("D", "DEM", "DEMAND"), {"RATE": _RATE, "POSITION": _POSITION,
                                        "OSCILLATOR": ("O", "OSC", "OSCILLATOR")}),
    "READ": (("R", "READ"), {"RATE": _RATE, "POSITION": _POSITION}),
    "INTERLOCK": (("I", "INT", "INTERLOCK"), {"CLOSE": ("C", "CLOS", "CLOSE"), "OPEN": ("O", "OPEN"),
                                              "RESET": ("R", "RES", "RESET")}),
    "LIMIT": (("L", "LIM", "LIMIT"), {"ACCELERATION": ("A", "ACC", "ACCELERATION")}),
    "UTILITY": (("U", "UTIL", "UTILITY"), {"LOCKOUT": ("L", "LOCK", "LOCKOUT")}),
    "QUERY": (("Q", "QUER", "QUERY"), {"ERROR": ("E", "ERR", "ERROR")}),
}
_ROOT_ALIASES = {alias: root for root, (aliases, _) in _NODES.items() for alias in aliases}


@dataclass(frozen=True)
class AclCommand:
    """One command of a line: canonical header path, query flag, raw arguments."""

    text: str
    path: tuple[str, ...] | None  # None: the header is not in the command set
    query: bool
    args: tuple[str, ...]

    @property
    def is_setting(self) -> bool:
        return not self.query


class CommandFailed(Exception):
    """Raised inside a handler: the command is refused with this (code, text)."""

    def __init__(self, error: tuple[int, str], detail: str = "") -> None:
        super().__init__(detail)
        self.error = error
        self.detail = detail


def _path(header: str) -> tuple[str, ...] | None:
    nodes = [n for n in header.split(":") if n]
    if not header.startswith(":") or not 1 <= len(nodes) <= 2 or nodes[0] not in _ROOT_ALIASES:
        return None
    root = _ROOT_ALIASES[nodes[0]]
    if len(nodes) == 1:
        return (root,)
    leaves = _NODES[root][1]
    leaf = next((name for name, aliases in leaves.items() if nodes[1] in aliases), None)
    return None if leaf is None else (root, leaf)


def parse_command(text: str) -> AclCommand:
    """Split ``:DEM:RATE 1,20`` into its canonical path, query flag and arguments."""
    text = text.strip()
    header, _, arg_text = text.replace("\t", " ").partition(" ")
    args = tuple(a.strip() for a in arg_text.split(",")) if arg_text.strip() else ()
    header = header.upper()
    query = header.endswith("?")
    header = header.rstrip("?")
    if header.startswith("*"):
        return AclCommand(text, (header,), query, args)
    path = _path(header)
    if path is not None and path[0] == "READ":
        query = True  # the manual lets these queries omit the ? (ACT2000 compatibility, §4.10.4, §4.10.5)
    return AclCommand(text, path, query, args)


def parse_line(line: str) -> list[AclCommand]:
    return [parse_command(part) for part in line.split(";") if part.strip()]


class AcutrolInterpreter:
    """Executes parsed commands against the physics and keeps the status registers."""

    def __init__(self, physics: TablePhysics, idn: str, axes: tuple[int, ...] = (1,)) -> None:
        self.physics = physics
        self.idn = idn
        self.axes = axes
        #: True while the (simulated) safety chain is broken: the interlock cannot close.
        self.safety_chain_open = False
        self.remote_lockout = False
        self.position_demand_deg = 0.0
        self.oscillator = (0.0, 0.0, 0.0)
        self._esr = 0                 # latched *ESR? bits, cleared by reading
        self._stb_latched = 0         # latched *STB? bits, cleared by reading
        self._lock = threading.Lock()
        self._handlers: dict[tuple[tuple[str, ...], bool], Callable[[AclCommand], str | None]] = {
            (("*IDN",), True): lambda c: self._no_args(c) or self.idn,
            (("*CLS",), False): self._clear_status,
            (("*ESR",), True): self._read_esr,
            (("*STB",), True): self._read_stb,
            (("MODE",), True): self._mode_query,
            (("MODE", "RATE"), False): self._mode_rate,
            (("MODE", "OFF"), False): self._mode_off,
            (("MODE", "POSITION"), False): self._mode_position,
            (("MODE", "SYNTHESIS"), False): self._mode_synthesis,
            (("DEMAND", "RATE"), False): self._demand_rate,
            (("DEMAND", "RATE"), True): self._demand_rate_query,
            (("DEMAND", "POSITION"), False): self._demand_position,
            (("DEMAND", "OSCILLATOR"), False): self._demand_oscillator,
            (("DEMAND", "OSCILLATOR"), True): self._demand_oscillator_query,
            (("READ", "RATE"), True): self._read_rate,
            (("READ", "POSITION"), True): self._read_position,
            (("INTERLOCK",), True): self._interlock_query,
            (("INTERLOCK", "CLOSE"), False): self._interlock_close,
            (("INTERLOCK", "OPEN"), False): self._interlock_open,
            (("INTERLOCK", "RESET"), False): self._no_args,
            (("LIMIT", "ACCELERATION"), False): self._limit_acc,
            (("LIMIT", "ACCELERATION"), True): self._limit_acc_query,
            (("QUERY", "ERROR"), True): self._error_text,
            (("UTILITY", "LOCKOUT"), False): self._lockout,
        }

    def latch_bad_message(self) -> None:
        """``*ESR?`` bit 2: a bad device-dependent message was received (Table 1, p. 19)."""
        with self._lock:
            self._esr |= proto.ESR_BAD_MESSAGE

    # ----- execution ----------------------------------------------------------------------

    def execute(self, command: AclCommand) -> tuple[int, str | None]:
        """Run one command: (0, its message or None) or (error code, None)."""
        handler = self._handlers.get((command.path, command.query)) if command.path else None
        try:
            if handler is None:
                raise CommandFailed(ERR_UNDEFINED_HEADER, command.text)
            return 0, handler(command)
        except CommandFailed as exc:
            with self._lock:
                if exc.error == ERR_BAD_PARAMETER:
                    self._esr |= proto.ESR_BAD_MESSAGE
                if exc.error == ERR_INTERLOCK_OPEN:
                    self._stb_latched |= proto.STB_SYSTEM_INTERLOCKS
            return exc.error[0], None

    def execute_line(self, commands: list[AclCommand]) -> tuple[int, str]:
        """Run the commands of one line: (first nonzero code or 0, query messages joined by ;)."""
        code, messages = 0, []
        for command in commands:
            result, message = self.execute(command)
            code = code or result
            if message is not None:
                messages.append(message)
        return code, ";".join(messages)

    # ----- argument helpers ---------------------------------------------------------------

    @staticmethod
    def _no_args(command: AclCommand) -> None:
        if command.args:
            raise CommandFailed(ERR_BAD_PARAMETER, command.text)

    @staticmethod
    def _arity(command: AclCommand, count: int) -> tuple[str, ...]:
        if len(command.args) != count or any(not a for a in command.args):
            raise CommandFailed(ERR_BAD_PARAMETER, command.text)
        return command.args

    @staticmethod
    def _number(text: str, command: AclCommand) -> float:
        try:
            value = float(text)
        except ValueError:
            raise CommandFailed(ERR_BAD_PARAMETER, command.text) from None
        if not math.isfinite(value):
            raise CommandFailed(ERR_BAD_PARAMETER, command.text)
        return value

    def _axis(self, text: str, command: AclCommand) -> int:
        value = self._number(text, command)
        if value != int(value) or int(value) not in self.axes:
            raise CommandFailed(ERR_BAD_PARAMETER, f"axis {text}")
        return int(value)

    def _refusing(self, action: Callable[[], None]) -> None:
        """Turn the physics' refusals into the matching errors."""
        try:
            action()
        except TableInterlockError as exc:
            raise CommandFailed(ERR_INTERLOCK_OPEN, str(exc)) from None
        except TableLimitError as exc:
            raise CommandFailed(ERR_BAD_PARAMETER, str(exc)) from None
        except TableModeError as exc:
            raise CommandFailed(ERR_SETTINGS_CONFLICT, str(exc)) from None

    # ----- handlers -----------------------------------------------------------------------

    def _clear_status(self, command: AclCommand) -> None:
        self._no_args(command)
        with self._lock:
            self._esr = self._stb_latched = 0

    def _read_esr(self, command: AclCommand) -> str:
        self._no_args(command)
        with self._lock:
            value, self._esr = self._esr, 0
        return str(value)

    def _read_stb(self, command: AclCommand) -> str:
        """Bit 0 while the interlock chain is faulted or since a refusal for it (then cleared)."""
        self._no_args(command)
        with self._lock:
            value, self._stb_latched = self._stb_latched, 0
        if self.safety_chain_open:
            value |= proto.STB_SYSTEM_INTERLOCKS
        return str(value)

    def _error_text(self, command: AclCommand) -> str:
        (code_text,) = self._arity(command, 1)
        code = self._number(code_text, command)
        return ERROR_TEXTS.get(int(code), "Unknown error code") if code == int(code) else "Unknown"

    def _not_simulated(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        raise CommandFailed(ERR_NOT_SIMULATED, command.text)

    def _mode_rate(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self._refusing(self.physics.set_mode_rate)

    def _mode_position(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self._refusing(self.physics.set_mode_position)

    def _mode_off(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self.physics.set_mode_off()

    def _mode_query(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        modes = {MODE_RATE: proto.TableMode.RATE, MODE_SYNTHESIS: proto.TableMode.SYNTHESIS,
                 MODE_POSITION: proto.TableMode.POSITION}
        return modes.get(self.physics.mode, proto.TableMode.OFF).value

    def _mode_synthesis(self, command: AclCommand) -> None:
        """§4.7.6: the sinusoid loaded by :Demand:Oscillator; none loaded is a settings conflict."""
        self._axis(*self._arity(command, 1), command)
        magnitude, frequency_hz, phase_deg = self.oscillator
        if frequency_hz <= 0:
            raise CommandFailed(ERR_SETTINGS_CONFLICT, "no oscillator loaded")
        self._refusing(lambda: self.physics.set_mode_synthesis(magnitude, frequency_hz, phase_deg))

    def _demand_rate(self, command: AclCommand) -> None:
        axis_text, rate_text = self._arity(command, 2)
        self._axis(axis_text, command)
        rate_dps = self._number(rate_text, command)
        self._refusing(lambda: self.physics.set_rate_demand_dps(rate_dps))

    def _demand_rate_query(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.demand_dps:.6f}"

    def _demand_position(self, command: AclCommand) -> None:
        axis_text, position_text = self._arity(command, 2)
        self._axis(axis_text, command)
        self.position_demand_deg = self._number(position_text, command)
        if self.physics.mode == MODE_POSITION:
            demand = self.position_demand_deg
            self._refusing(lambda: self.physics.set_position_demand_deg(demand))

    def _demand_oscillator(self, command: AclCommand) -> None:
        axis_text, *values = self._arity(command, 4)
        self._axis(axis_text, command)
        magnitude, frequency_hz, phase_deg = (self._number(v, command) for v in values)
        if frequency_hz <= 0:
            raise CommandFailed(ERR_BAD_PARAMETER, f"frequency {frequency_hz}")
        self.oscillator = (magnitude, frequency_hz, phase_deg)

    def _demand_oscillator_query(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return ";".join(f"{value:.6f}" for value in self.oscillator)

    def _read_rate(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.read_rate_dps():.6f}"

    def _read_position(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        return f"{self.physics.position_deg():.6f}"

    def _interlock_query(self, command: AclCommand) -> str:
        self._axis(*self._arity(command, 1), command)
        if self.physics.interlock_closed:
            return proto.InterlockState.CLOSE.value
        return (proto.InterlockState.FAULT if self.safety_chain_open else proto.InterlockState.OPEN).value

    def _interlock_close(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        if self.safety_chain_open:
            raise CommandFailed(ERR_INTERLOCK_OPEN, "safety chain open, interlock cannot close")
        self.physics.close_interlock()

    def _interlock_open(self, command: AclCommand) -> None:
        self._axis(*self._arity(command, 1), command)
        self.physics.open_interlock()

    def _lockout(self, command: AclCommand) -> None:
        (state,) = self._arity(command, 1)
        if state.upper() not in ("ON", "OFF"):
            raise CommandFailed(ERR_BAD_PARAMETER, f"lockout {state!r}")
        self.remote_lockout = state.upper() == "ON"

    def _limit_mode(self, text: str, command: AclCommand) -> None:
        """§4.6: the profiler mode is one character (R rate); only rate mode is simulated."""
        if text.upper() not in ("R", "RATE"):
            other_mode = text.upper() in {"A", "O", "P", "S", "T"}
            raise CommandFailed(ERR_NOT_SIMULATED if other_mode else ERR_BAD_PARAMETER, command.text)

    def _limit_acc(self, command: AclCommand) -> None:
        mode_text, axis_text, accel_text = self._arity(command, 3)
        self._limit_mode(mode_text, command)
        self._axis(axis_text, command)
        accel_dps2 = self._number(accel_text, command)
        self._refusing(lambda: self.physics.set_accel_limit_dps2(accel_dps2))

    def _limit_acc_query(self, command: AclCommand) -> str:
        mode_text, axis_text = self._arity(command, 2)
        self._limit_mode(mode_text, command)
        self._axis(axis_text, command)
        return f"{self.physics.accel_limit_dps2:.6f}"
