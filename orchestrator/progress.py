"""A live progress line for a person at a terminal; silence otherwise.

Overnight runs are mostly watched through ``gyrocal status`` and the journal;
the live line is for the engineer who starts the run, so it only appears when
stderr is a terminal (CI logs and cron mails stay clean).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

from rich.console import Console

from gyrocal.units import format_hms


@dataclass
class ProgressState:
    step_id: str = "-"
    step_index: int = 0
    step_count: int = 0
    chamber_c: float | None = None
    table_dps: float | None = None
    elapsed_s: float = 0.0
    eta_s: float | None = None          # the plan's time to go when the step started
    step_expected_s: float = 0.0        # the plan's duration of the current step
    step_started_s: float | None = None  # elapsed_s when it started (None: ETA as given)
    paused: bool = False

    def eta_now_s(self) -> float | None:
        """The ETA counted down through the step (a long soak or hold keeps moving the line),
        never below the later steps' plan: an overrunning step holds the ETA, not negative."""
        if self.eta_s is None or self.step_started_s is None:
            return self.eta_s
        later_s = self.eta_s - self.step_expected_s
        return max(later_s, self.eta_s - (self.elapsed_s - self.step_started_s))


class Progress:
    def __init__(self, enabled: bool | None = None, min_interval_s: float = 0.2) -> None:
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.state = ProgressState()
        self._last_wall = 0.0
        self._line_open = False   # a live line is on the terminal, not yet ended by a newline
        self._min_interval_s = min_interval_s
        self._console = None
        if self.enabled:

            self._console = Console(stderr=True)

    def line(self) -> str:
        s = self.state
        chamber = "--" if s.chamber_c is None else f"{s.chamber_c:7.2f} °C"
        table = "--" if s.table_dps is None else f"{s.table_dps:8.2f} °/s"
        paused = "PAUSED (delete RUN_DIR/PAUSE to go on)  " if s.paused else ""
        return (f"{paused}[{s.step_index}/{s.step_count}] {s.step_id:<28} chamber {chamber}  "
                f"table {table}  elapsed {format_hms(s.elapsed_s, live=True)}  "
                f"ETA {format_hms(s.eta_now_s(), live=True)}")

    def update(self, **fields: object) -> None:
        for key, value in fields.items():
            setattr(self.state, key, value)
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last_wall < self._min_interval_s:
            return
        self._last_wall = now
        assert self._console is not None
        self._console.print(self.line(), end="\r", highlight=False, soft_wrap=True)
        self._line_open = True

    def close(self) -> None:
        """End the live line (once: the safe state closes it before printing, the run again)."""
        if self.enabled and self._console is not None and self._line_open:
            self._console.print()
        self._line_open = False
