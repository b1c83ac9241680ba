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
STATUS_QUERY = Command(
    ";".join((READ_RATE.template, READ_POSITION.template, INTERLOCK_QUERY.template)),
    parse_status,
)

#: Error-queue entries drained after a refusal (the controller's queue depth).
MAX_QUEUED_ERRORS = 16
