"""The shortest run that still has every record kind: one temperature, a static, a ± pair.

Used where a test repeats a whole run per record boundary (kill -9, signals),
so each repetition costs a fraction of a second of simulated time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

SHORT_PLAN = ("T01.ramp", "T01.soak", "T01.static", "T01.sf.+20dps", "T01.sf.-20dps")


def short_procedure(h: Any, folder: Path) -> Path:
    """The engine tests' small procedure (``h.write_procedure``) cut to its first temperature."""
    path = h.write_procedure(folder)
    text = path.read_text()
    cut = text.index("  - setpoint_c: 27.0")
    path.write_text(text[:cut])
    return path
