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


class InstrumentTimeout(InstrumentError):
    """No (complete) reply within the timeout. Transient by default."""

    def __init__(self, instrument: str, command: str, detail: str = "no reply", reply=None):
        super().__init__(instrument, command, detail, reply, transient=True)


class InstrumentConnectionError(InstrumentError):
    """The transport is gone (refused, reset, closed). Transient: reconnect and retry."""

    def __init__(self, instrument: str, command: str, detail: str, reply=None):
        super().__init__(instrument, command, detail, reply, transient=True)


class InstrumentProtocolError(InstrumentError):
    """A reply that does not parse, or a protocol-level refusal (Modbus exception, SCPI error)."""


class InstrumentSafetyError(InstrumentError):
    """The instrument reports a condition that requires the safe state (alarm, interlock open)."""
