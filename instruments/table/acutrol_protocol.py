"""The ACUTROL3000 command set in one declaration: what is sent, and how replies parse.

Keeping every command string here means the driver methods stay one line each
and a firmware difference (a renamed header, a reordered argument) is a
one-line change. Sources and assumptions:

- ``:mode:rate``, ``:mode:off``, ``:demand:rate``, ``:read:rate?``, ``:read:pos?``,
  ``:interlock?``, ``:interlock:close`` with the axis number after the header,
  and ``;`` joining several commands on one line, follow public scripts that
  drive real ACUTROL controllers (no manual was available here).
- ``:limit:acc rate,<axis>,<deg/s^2>`` (mode name first, then axis) follows a
  public pyvisa script for an ACUTROL3000; the other modes' limits (pos, synt)
  are not used.
- ``:syst:err?`` answering ``<code>,"<message>"`` (0 = no error) and ``*CLS``
  are SCPI-standard. **Assumption:** a refusal because the interlock is open
  carries the device-specific code 201 or mentions "interlock"; the driver
  raises such refusals (a motion command, or closing the interlock while the
  safety chain is broken) as safety errors.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: Device-specific SCPI error codes that mean "the interlock is open".
INTERLOCK_ERROR_CODES = frozenset({201})


class ReplyFormatError(ValueError):
    """A reply that does not have the shape its command promises."""


@dataclass(frozen=True)
class Command:
    """One entry of the command set.

    ``parse`` is None for settings: they send no reply, so the driver appends
    the error query to the same line and checks the answer (one round trip).
    """

    template: str
    parse: Callable[[str], Any] | None = None

    def text(self, **fields: Any) -> str:
        return self.template.format(**fields)


def _printable(reply: str) -> str:
    if not reply or not reply.isprintable() or not reply.isascii():
        raise ReplyFormatError("not printable ASCII")
    return reply.strip()


def parse_float(reply: str) -> float:
    try:
        value = float(_printable(reply))
    except ValueError:
        raise ReplyFormatError("expected a number") from None
    if not math.isfinite(value):
        raise ReplyFormatError("expected a finite number")
    return value


def parse_interlock_closed(reply: str) -> bool:
    text = _printable(reply)
    if text not in ("0", "1"):
        raise ReplyFormatError("expected 1 (closed) or 0 (open)")
    return text == "1"


def parse_identity(reply: str) -> str:
    text = _printable(reply)
    if len(text.split(",")) != 4:
        raise ReplyFormatError("expected manufacturer,model,serial,firmware")
    return text


_ERROR_REPLY = re.compile(r'^([+-]?\d+),"(.*)"$')


def parse_error(reply: str) -> tuple[int, str]:
    match = _ERROR_REPLY.match(_printable(reply))
    if match is None:
        raise ReplyFormatError('expected <code>,"<message>"')
    return int(match.group(1)), match.group(2)


_ERROR_CODE = re.compile(r"([+-]\d{3})\b")


def error_code_in(reply: str) -> int | None:
    """The SCPI error code a refusal carries (``ERROR -200,"Execution error"``), if any."""
    match = _ERROR_CODE.search(reply)
    return int(match.group(1)) if match else None


#: SCPI parameter errors inside the execution class: the value itself is wrong
#: (-220 parameter error, -222 data out of range, -223 too much data, -224 illegal
#: parameter value, -225 out of memory, -226 lists not same length).
PARAMETER_ERROR_CODES = frozenset({-220, -222, -223, -224, -225, -226})


def refusal_may_pass(code: int | None) -> bool:
    """Whether sending the same setting again may succeed.

    SCPI-99 error/event classes: -100…-199 are command errors (syntax, bad header: the
    same bytes fail again), and the parameter errors above say the value is wrong; the
    other execution errors (-200 execution error, -221 settings conflict, -230/-240 data
    or hardware trouble), device-specific (-3xx) and query (-4xx) errors depend on the
    table's state and may pass on a later attempt. A refusal without a code is treated
    as retryable: the station's ``retries`` bound it.
    """
    if code is None:
        return True
    return not (-199 <= code <= -100 or code in PARAMETER_ERROR_CODES)


def parse_status(reply: str) -> tuple[float, float, bool]:
    fields = _printable(reply).split(";")
    if len(fields) != 3:
        raise ReplyFormatError("expected rate;position;interlock")
    return parse_float(fields[0]), parse_float(fields[1]), parse_interlock_closed(fields[2])


def commanded_rate_dps(rate_dps: float) -> float:
    """The rate the table receives for a demand of ``rate_dps`` (the wire's resolution)."""
    return float(f"{rate_dps:.{RATE_DECIMALS}f}")


def is_interlock_error(code: int, message: str) -> bool:
    return code in INTERLOCK_ERROR_CODES or "interlock" in message.lower()


# ----- the command set ----------------------------------------------------------------------

IDENTIFY = Command("*IDN?", parse_identity)
CLEAR_STATUS = Command("*CLS")
ERROR_QUERY = Command(":syst:err?", parse_error)

MODE_RATE = Command(":mode:rate {axis}")
MODE_OFF = Command(":mode:off {axis}")
#: The rate a demand carries: fixed point with RATE_DECIMALS places. The plan rounds its rates
#: with :func:`commanded_rate_dps`, so the rate analysed is the rate sent, to the last digit.
RATE_DECIMALS = 6
DEMAND_RATE = Command(":demand:rate {axis}, {rate_dps:." + str(RATE_DECIMALS) + "f}")
LIMIT_ACCELERATION = Command(":limit:acc rate,{axis}, {accel_dps2:.6f}")
LIMIT_ACCELERATION_QUERY = Command(":limit:acc? rate,{axis}", parse_float)

READ_RATE = Command(":read:rate? {axis}", parse_float)
READ_POSITION = Command(":read:pos? {axis}", parse_float)
INTERLOCK_QUERY = Command(":interlock? {axis}", parse_interlock_closed)
INTERLOCK_CLOSE = Command(":interlock:close {axis}")

#: Rate, position and interlock in one round trip.
# ----- dialects -------------------------------------------------------------------------------

LOCKOUT_ON = Command(":utility:lockout on")
INTERLOCK_OPEN = Command(":interlock:open {axis}")
INTERLOCK_RESET = Command(":interlock:reset {axis}")
READ_RATE_PLAIN = Command(":read:rate {axis}", parse_float)
READ_POSITION_PLAIN = Command(":read:position {axis}", parse_float)


@dataclass(frozen=True)
class Dialect:
    """How a controller answers: a declared, tested property of the driver.

    ``acknowledged``: every command line gets exactly one reply, ``OK`` for an
    accepted setting; ``reply_prefix`` characters precede every reply's value;
    ``startup`` runs when a session opens. Without acknowledgement (the SCPI
    error-queue form) settings are silent and ``:syst:err?`` on the same line
    says whether they were accepted.
    """

    name: str
    acknowledged: bool
    reply_prefix: int
    terminator: str
    startup: tuple[Command, ...]       # the first session of a driver
    reconnect: tuple[Command, ...]     # a session reopened after a transport fault
    read_rate: Command
    read_position: Command
    source: str


#: The one public script that drives a real ACUTROL over raw TCP (a ROS node for an
#: AC117 table, AcutronicRobotics/acutrol: ``acutrol.py`` with ``ac117.json``): CR LF,
#: every reply read as ``recv(1024)[8:]`` (an 8-character prefix), ``:read:rate 1`` /
#: ``:read:position 1`` without ``?``. ``ac117.json`` spells the start-up list and its
#: expected answers exactly: ``[":utility:lockout on", "OK"], [":interlock:open 1", "OK"],
#: [":interlock:reset 1", "OK"], [":interlock:close 1", "OK"]`` (shutdown: ``:mode:off 1``,
#: ``:interlock:open 1``). The prefix's content is not known (only its length); whether
#: replies end in CR LF is unconfirmed (the script compares ``[8:]`` with ``"OK"``
#: unstripped, which would hold only without a terminator, but never checks the result).
ACUTROL_TCP_SCRIPT = Dialect(
    "acutrol-tcp-script", acknowledged=True, reply_prefix=8, terminator="\r\n",
    startup=(LOCKOUT_ON, INTERLOCK_OPEN, INTERLOCK_RESET, INTERLOCK_CLOSE),
    # never the interlock again after a reconnect: opening it would stop a table mid-dwell
    reconnect=(LOCKOUT_ON,),
    read_rate=READ_RATE_PLAIN, read_position=READ_POSITION_PLAIN,
    source="public ROS script for an AC117 on an ACUTROL (raw TCP)")

#: The SCPI-standard form the project used first: silent settings, ``:syst:err?``
#: polling, ``?`` queries, LF. Kept as a named alternative for controllers set up
#: for SCPI error-queue reporting (no ACUTROL document confirms it).
SCPI_ERROR_QUEUE = Dialect(
    "scpi-error-queue", acknowledged=False, reply_prefix=0, terminator="\n", startup=(),
    reconnect=(),
    read_rate=READ_RATE, read_position=READ_POSITION,
    source="SCPI-1999 error queue (unconfirmed for ACUTROL)")

DIALECTS = {d.name: d for d in (ACUTROL_TCP_SCRIPT, SCPI_ERROR_QUEUE)}
DEFAULT_DIALECT = ACUTROL_TCP_SCRIPT.name


def strip_prefix(reply: str, dialect: Dialect) -> str:
    """The value after the prefix; a reply with non-printable bytes anywhere is corrupt."""
    if not (reply.isascii() and reply.isprintable()):
        raise ReplyFormatError("not printable ASCII")
    if len(reply) < dialect.reply_prefix:
        raise ReplyFormatError(f"shorter than the dialect's {dialect.reply_prefix}-character prefix")
    return reply[dialect.reply_prefix:].strip()


STATUS_QUERY = Command(
    ";".join((READ_RATE.template, READ_POSITION.template, INTERLOCK_QUERY.template)),
    parse_status,
)

#: Error-queue entries drained after a refusal (the controller's queue depth).
MAX_QUEUED_ERRORS = 16
