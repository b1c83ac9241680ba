"""The ACUTROL3000 command language (ACL) as the driver and the simulator use it.

Every command string and reply rule is declared here once, with the manual
section it comes from (Acutronic TM-8004-C "ACUTROL3000 Command Language
(ACL) Programming Manual"; TM-9384C "Using the Acutrol3000 TCP/IP
Interface"; TM-9374A "Real Time Data Communication Manual"). Spellings are
the manual's long forms; the controller accepts them case-insensitively.

Reply framing over TCP (``frame_reply`` / ``ReplyHeader``):

- TM-8004 §2 (p. 2): on every interface but IEEE-488 each command receives a
  response, and the response carries an error code and a message length
  prefixed to the data a query asked for;
- TM-9374A §3.4.2 (p. 34), for the ACL channel: the first 32-bit word is the
  error return of the command, the second the length of the response message
  in characters, then the message, null-terminated;
- TM-8004 §5.1.1 (p. 206): the controller is an Intel machine, binary data
  little-endian; so both words are read as little-endian signed 32-bit.
- A public script for a real table (AcutronicRobotics/acutrol ``acutrol.py``)
  drops exactly 8 bytes before each reply, which agrees with two 32-bit words.

**Unconfirmed**: whether the length counts the terminating NUL. The driver
reads exactly ``length`` bytes after the header and drops trailing NULs, so a
reply framed either way with its NUL inside the count is read correctly.

Errors (§4.9.1 p. 163, §3.3 p. 14, §3.10 p. 19, Table 1 p. 19): error code 0
is success; the text of any other code comes from ``:Query:Error? <code>``.
The code list itself is "TBD" in TM-8004 (§6.1 p. 213), so the driver never
interprets a code's number: ``*STB?`` bit 0 (summary of the system
interlocks) says the refusal is a safety stop, and ``*ESR?`` bit 2 (a bad
device-dependent message: axis out of range, wrong data) says that sending
the same bytes again cannot succeed. There is no ``:SYST:ERR?`` in the ACL.
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: TCP port of the real-time computer's ACL server (TM-9384C §1, p. 1; TM-9411 §4.1.1, p. 4).
ACL_TCP_PORT = 9878
#: A command ends with a line feed (TM-8004 §2.4, p. 4; TM-9374A §3.4.2, p. 34).
COMMAND_TERMINATOR = "\n"
#: The longest response message the controller sends (TM-8004 §2.5, p. 5: 32 K characters).
MAX_MESSAGE_CHARS = 32768
#: Two little-endian signed 32-bit words: error code, message length (see the module doc).
HEADER = struct.Struct("<ii")

#: ``*STB?`` bits (TM-8004 §3.10, p. 19).
STB_SYSTEM_INTERLOCKS = 1 << 0
STB_ERROR_QUEUE = 1 << 7
#: ``*ESR?`` bits (TM-8004 Table 1, p. 19).
ESR_MIS_SERVO_FAULT = 1 << 0
ESR_BAD_MESSAGE = 1 << 2
ESR_AXIS_TIMED_OUT = 1 << 5

#: The dialects a station may declare (``table.dialect``). Only the manual's: the earlier
#: text-line dialects contradicted TM-8004 §2 (an ASCII prefix, ``:syst:err?``) and no
#: public script needs them.
ACL_TCP = "acl-tcp"
DIALECTS = (ACL_TCP,)
DEFAULT_DIALECT = ACL_TCP


class ReplyFormatError(ValueError):
    """A reply that does not have the shape its command promises."""


@dataclass(frozen=True)
class ReplyHeader:
    """The 8-byte prefix of every reply: the command's error code and the message length."""

    error_code: int
    length: int

    @classmethod
    def decode(cls, raw: bytes) -> ReplyHeader:
        if len(raw) != HEADER.size:
            raise ReplyFormatError(f"reply header is {len(raw)} bytes, expected {HEADER.size}")
        code, length = HEADER.unpack(raw)
        if not 0 <= length <= MAX_MESSAGE_CHARS:
            raise ReplyFormatError(f"reply header announces {length} characters "
                                   f"(0..{MAX_MESSAGE_CHARS}, TM-8004 §2.5)")
        return cls(code, length)


def frame_reply(error_code: int, message: str) -> bytes:
    """Header + message + NUL, the NUL counted in the length (the simulator's framing)."""
    body = message.encode("latin-1") + b"\x00"
    return HEADER.pack(error_code, len(body)) + body


def message_text(body: bytes) -> str:
    """The message of a reply body: trailing NULs dropped; anything unprintable is corrupt."""
    text = body.rstrip(b"\x00").decode("latin-1")
    if not (text.isascii() and text.isprintable()):
        raise ReplyFormatError("not printable ASCII")
    return text.strip()


# ----- reply parsers ----------------------------------------------------------------------------

def parse_float(reply: str) -> float:
    try:
        value = float(reply)
    except ValueError:
        raise ReplyFormatError("expected a number") from None
    if not math.isfinite(value):
        raise ReplyFormatError("expected a finite number")
    return value


def parse_register(reply: str) -> int:
    """An NR1 register value 0..255 (``*ESR?``, ``*STB?``)."""
    if not reply.isdigit() or not 0 <= int(reply) <= 255:
        raise ReplyFormatError("expected an integer 0..255")
    return int(reply)


class InterlockState(enum.Enum):
    """The interlock states the manual names (TM-8004 §4.5.3, p. 133: Close, Open, Fault)."""

    CLOSE = "Close"
    OPEN = "Open"
    FAULT = "Fault"


def parse_interlock(reply: str) -> InterlockState:
    """``:Interlock? <axis>`` (TM-8004 Table 6, p. 24). The manual documents the interlock
    state answer as one of Close, Open, Fault (§4.5.3, p. 133; a public script for a real
    unit compares the answer with ``Fault``); the single initial is accepted too."""
    word = reply.strip().upper()
    for state in InterlockState:
        if word in (state.value.upper(), state.value[0].upper()):
            return state
    raise ReplyFormatError("expected Close, Open or Fault")


class TableMode(enum.Enum):
    """Servo modes and the letter ``:Mode? <axis>`` answers (TM-8004 §4.7, p. 147)."""

    POSITION = "P"
    RATE = "R"
    ARATE = "A"
    SYNTHESIS = "S"
    TRACK = "T"
    OFF = "O"


def parse_mode(reply: str) -> TableMode:
    text = reply.strip().upper()
    for mode in TableMode:
        if text in (mode.value, mode.name):
            return mode
    raise ReplyFormatError("expected a mode letter P, R, A, S, T or O")


def parse_identity(reply: str) -> str:
    """``*IDN?``: manufacturer,model,serial number,software level (TM-8004 §3.4, p. 15)."""
    if len(reply.split(",")) != 4:
        raise ReplyFormatError("expected manufacturer,model,serial,software level")
    return reply


def parse_text(reply: str) -> str:
    return reply


# ----- the command set --------------------------------------------------------------------------

@dataclass(frozen=True)
class Command:
    """One ACL command; ``parse`` reads a query's message (None for a setting)."""

    template: str
    parse: Callable[[str], Any] | None = None

    def text(self, **fields: Any) -> str:
        return self.template.format(**fields)


#: The demand's fixed-point resolution. The plan rounds its rates with
#: :func:`commanded_rate_dps`, so the rate analysed is the rate sent, to the last digit.
RATE_DECIMALS = 6


def commanded_rate_dps(rate_dps: float) -> float:
    """The rate the table receives for a demand of ``rate_dps`` (the wire's resolution)."""
    return float(f"{rate_dps:.{RATE_DECIMALS}f}")


IDENTIFY = Command("*IDN?", parse_identity)                                  # §3.4 p. 15
EVENT_STATUS = Command("*ESR?", parse_register)                              # §3.3 p. 14
STATUS_BYTE = Command("*STB?", parse_register)                               # §3.10 p. 19
ERROR_TEXT = Command(":Query:Error? {code}", parse_text)                     # §4.9.1 p. 163
LOCKOUT_ON = Command(":Utility:Lockout ON")                                  # §4.14.2 p. 196

MODE_QUERY = Command(":Mode? {axis}", parse_mode)                            # §4.7 p. 147
MODE_OFF = Command(":Mode:Off {axis}")                                       # §4.7.3 p. 150
MODE_POSITION = Command(":Mode:Position {axis}")                             # §4.7.4 p. 151
MODE_RATE = Command(":Mode:Rate {axis}")                                     # §4.7.5 p. 152
MODE_SYNTHESIS = Command(":Mode:Synthesis {axis}")                           # §4.7.6 p. 153

DEMAND_POSITION = Command(":Demand:Position {axis},{position_deg:.6f}")       # §4.3.5 p. 112
DEMAND_RATE = Command(f":Demand:Rate {{axis}},{{rate_dps:.{RATE_DECIMALS}f}}")  # §4.3.6 p. 113
#: §4.3.4 p. 111: <axis>,<magnitude>,<frequency Hz>,<phase deg>; the magnitude is of the state
#: set by Configure:Oscillator (position by default: "peak position displacement").
DEMAND_OSCILLATOR = Command(":Demand:Oscillator {axis},{magnitude:.6f},{frequency_hz:.6f},"
                            "{phase_deg:.6f}")
DEMAND_RATE_QUERY = Command(":Demand:Rate? {axis}", parse_float)             # §4.3.6 p. 113

#: §4.6.2 p. 139: <mode>,<axis>,<limit>; the mode is one character (§4.6 p. 137: R = rate).
LIMIT_ACCELERATION = Command(":Limit:Acceleration R,{axis},{accel_dps2:.6f}")
LIMIT_ACCELERATION_QUERY = Command(":Limit:Acceleration? R,{axis}", parse_float)

READ_POSITION = Command(":Read:Position? {axis}", parse_float)               # §4.10.4 p. 168
READ_RATE = Command(":Read:Rate? {axis}", parse_float)                       # §4.10.5 p. 169

INTERLOCK_QUERY = Command(":Interlock? {axis}", parse_interlock)             # Table 6 p. 24
INTERLOCK_CLOSE = Command(":Interlock:Close {axis}")                         # §4.5.1 p. 131
INTERLOCK_OPEN = Command(":Interlock:Open {axis}")                           # §4.5.5 p. 135
#: §4.5.6 p. 136: no argument — it unfreezes the interlock status of every faulted axis and
#: has no effect on an axis already servoed.
INTERLOCK_RESET = Command(":Interlock:Reset")
