"""Retries on the console: one line per streak of the same failure, with its count.

Every retry is journaled (the record keeps each attempt); the console is for a
person, and eight near-identical "attempt N failed … retrying" lines hid the one
line that mattered (issue 28). A streak — same instrument, same command, same
failure — is one line, printed when the streak ends (another failure, or the
run's next message), saying how many attempts it took. On a terminal the line
appears at the first retry and its count is rewritten in place as the streak
grows, so a person watching sees it at once.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TextIO

from gyrocal.instruments.errors import InstrumentError


@dataclass
class _Streak:
    role: str
    command: str
    detail: str
    reply: str | None
    count: int = 1


class RetryConsole:
    """Collects retries; ``flush`` prints the pending streak (call it before other output)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream
        self._streak: _Streak | None = None
        self.lines_printed = 0

    def note(self, role: str, exc: InstrumentError) -> None:
        reply = exc.reply if isinstance(exc.reply, str) or exc.reply is None else repr(exc.reply)
        streak = self._streak
        if streak is not None and (streak.role, streak.command, streak.detail) == \
                (role, exc.command, exc.detail):
            streak.count += 1
            streak.reply = reply
        else:
            self.flush()
            self._streak = _Streak(role, exc.command, exc.detail, reply)
        if self._live:
            print(f"\r{self._text(self._streak)}", end="", file=self._out, flush=True)

    def flush(self) -> None:
        streak, self._streak = self._streak, None
        if streak is None:
            return
        print(("\r" if self._live else "") + self._text(streak), file=self._out, flush=True)
        self.lines_printed += 1

    @property
    def _out(self) -> TextIO:
        return self.stream or sys.stderr

    @property
    def _live(self) -> bool:
        return bool(getattr(self._out, "isatty", lambda: False)())

    @staticmethod
    def _text(streak: _Streak) -> str:
        times = "once" if streak.count == 1 else f"{streak.count} times"
        reply = f" (reply: {streak.reply})" if streak.reply else ""
        return f"gyrocal: {streak.role}: {streak.command}: {streak.detail}{reply}; retried {times}"
