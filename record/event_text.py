"""A journal event as a line a person reads: words and units, no hashes, no float noise.

The journal is for auditors and programs (every key, every digit, every hash); the live
page and ``gyrocal status`` show people what happened. Units come from the key names,
which carry them by the project's rule (``setpoint_c``, ``rate_dps``, ``ramp_s``).
"""

from __future__ import annotations

import math
from typing import Any

from gyrocal.record.journal import JournalEvent

#: Keys that identify or chain the event rather than say what happened (``sim_state``: a
#: dry run's simulated station, for a resumed run to restore, not for people).
HIDDEN_KEYS = frozenset({"seq", "wall_time", "event", "prev_sha256", "step_id", "signature",
                         "identity", "inputs", "sha256", "plan_sha256", "signing_key",
                         "before_step", "sim_state"})

#: Unit suffixes of key names, longest first, and how the unit is written for people.
UNIT_SUFFIXES = (
    ("_c_per_min", "°C/min"), ("_dph_per_c", "deg/h/°C"), ("_ppm_per_c", "ppm/°C"),
    ("_dps2", "deg/s²"), ("_dps", "deg/s"), ("_dph", "deg/h"), ("_hz", "Hz"), ("_pct", "%"),
    ("_ppm", "ppm"), ("_c", "°C"), ("_s", "s"), ("_deg", "deg"),
)


def quantity(key: str, value: float) -> tuple[str, str]:
    """``("setpoint_c", 20.0)`` -> ``("setpoint", "20 °C")``: a label and a value with its unit."""
    for suffix, unit in UNIT_SUFFIXES:
        if key.endswith(suffix) and len(key) > len(suffix):
            return key[: -len(suffix)].replace("_", " "), f"{number(value)} {unit}"
    return key.replace("_", " "), number(value)


def number(value: float) -> str:
    """Four significant digits: what a glance needs (the journal keeps them all)."""
    if isinstance(value, int) or (math.isfinite(value) and value == int(value) and abs(value) < 1e9):
        return str(int(value))
    return f"{value:.4g}"


def _value(key: str, value: Any) -> str | None:
    if key.endswith("sha256") or value is None:
        return None
    if isinstance(value, bool):
        return f"{key.replace('_', ' ')}: {'yes' if value else 'no'}"
    if isinstance(value, (int, float)):
        label, text = quantity(key, value)
        return f"{label} {text}"
    if isinstance(value, dict):
        return f"{key.replace('_', ' ')}: {', '.join(str(k) for k in value)}"
    if isinstance(value, list):
        return f"{key.replace('_', ' ')}: {', '.join(str(v) for v in value[:6])}"
    text = str(value)
    return f"{key.replace('_', ' ')} {text if len(text) <= 80 else text[:77] + '…'}"


def describe_event(event: dict[str, Any]) -> str:
    """What the event says, for people: its message, or its keys with units."""
    message = event.get("message") or event.get("description")
    if isinstance(message, str) and message:
        return message
    name = event.get("event")
    if name == JournalEvent.CHUNK_WRITTEN and isinstance(event.get("rows"), int):
        path = str(event.get("path", ""))
        return f"{event['rows']} samples written ({path.rsplit('/', 1)[-1]})"
    parts = []
    attempt = event.get("attempt")
    for key, value in sorted(event.items()):
        if key in HIDDEN_KEYS or key == "attempt" or key == "path":
            continue
        text = _value(key, value)
        if text:
            parts.append(text)
    if isinstance(attempt, int) and attempt > 1:
        parts.append(f"attempt {attempt}")
    return " · ".join(parts)
