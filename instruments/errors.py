"""Instrument errors that say which instrument, what command and what came back.

An operator reading the journal at 7 a.m. must see, without a traceback,
which box misbehaved and how. Every driver raises only these.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class InstrumentError(Exception):
    """A fault talking to an instrument.

    ``transient`` says whether retrying the same command may succeed (a
    timeout, a garbled reply) as opposed to a condition that needs the safe
    state (an alarm, an open interlock, a refused command).
    """

    instrument: str
    command: str
    detail: str
    reply: str | bytes | None = None
    transient: bool = False

    def __str__(self) -> str:
        text = f"{self.instrument}: {self.command}: {self.detail}"
        if self.reply is not None:
            text += f" (reply: {self.reply!r})"
        return text


#: Bytes of a binary reply shown in a message; the rest is counted, not dumped.
REPLY_HEX_BYTES = 16
#: Characters of a text reply shown in a message.
REPLY_TEXT_CHARS = 40


def describe_reply(data: bytes, protocol: str) -> str | None:
    """What came back, for a person: a text reply described as not the protocol, a binary one short.

    A chamber address that reaches a web server answers an RTU frame with
    "HTTP/1.1 400 Bad Request…": ninety hex bytes said nothing an operator could
    read; ``not a Modbus reply: 'HTTP/1.1 400 Bad Request'`` says what is there.
    """
    if not data:
        return None
    printable = sum(1 for b in data if 32 <= b < 127 or b in (9, 10, 13))
    if len(data) >= 4 and printable >= 0.9 * len(data):
        lines = data.decode("ascii", "replace").strip().splitlines() or [""]
        first = lines[0].strip()
        more = len(first) > REPLY_TEXT_CHARS or len(lines) > 1
        return f"not a {protocol} reply: {first[:REPLY_TEXT_CHARS]!r}" + ("…" if more else "")
    shown = data[:REPLY_HEX_BYTES].hex(" ")
    return shown + (f" … ({len(data)} bytes)" if len(data) > REPLY_HEX_BYTES else "")


class InstrumentTimeout(InstrumentError):
    """No (complete) reply within the timeout. Transient by default."""

    def __init__(self, instrument: str, command: str, detail: str = "no reply", reply=None):
        super().__init__(instrument, command, detail, reply, transient=True)


class InstrumentConnectionError(InstrumentError):
    """The transport is gone (refused, reset, closed). Transient: reconnect and retry."""

    def __init__(self, instrument: str, command: str, detail: str, reply=None):
        super().__init__(instrument, command, detail, reply, transient=True)


class InstrumentProtocolError(InstrumentError):
    """A reply that does not parse, or a protocol-level refusal (Modbus exception, ACUTROL error code)."""


class InstrumentSafetyError(InstrumentError):
    """The instrument reports a condition that requires the safe state (alarm, interlock open)."""
