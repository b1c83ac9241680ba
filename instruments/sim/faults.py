"""Faults injected on purpose into the simulated instruments.

Recovery code is only trustworthy if it has been exercised, so every
simulator consults one :class:`FaultInjector` on each request. A fault is
armed by name, for a number of requests (or until cleared), with optional
parameters. Each simulator documents the names it understands in its
``FAULTS`` tuple; arming an unknown name is an error, so a typo in a test
cannot silently test nothing.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any


@dataclass
class _Armed:
    remaining: int | None          # None = until cleared
    params: dict[str, Any] = field(default_factory=dict)
    fired: int = 0


class FaultInjector:
    """Thread-safe registry of armed faults for one simulator."""

    def __init__(self, known: tuple[str, ...], owner: str = "simulator") -> None:
        self.known = tuple(known)
        self.owner = owner
        self._armed: dict[str, _Armed] = {}
        self._lock = threading.Lock()
        self.history: list[str] = []

    def arm(self, name: str, count: int | None = 1, **params: Any) -> None:
        """Arm ``name`` for the next ``count`` requests (None: until :meth:`clear`)."""
        if name not in self.known:
            raise ValueError(f"{self.owner}: unknown fault {name!r}; known: {', '.join(self.known)}")
        if count is not None and count < 1:
            raise ValueError("count must be >= 1 or None")
        with self._lock:
            self._armed[name] = _Armed(count, dict(params))

    def clear(self, name: str | None = None) -> None:
        with self._lock:
            if name is None:
                self._armed.clear()
            else:
                self._armed.pop(name, None)

    def is_armed(self, name: str) -> bool:
        with self._lock:
            return name in self._armed

    def params(self, name: str) -> dict[str, Any] | None:
        """Parameters of an armed fault without consuming it (for persistent conditions)."""
        with self._lock:
            armed = self._armed.get(name)
            return dict(armed.params) if armed else None

    def take(self, name: str) -> dict[str, Any] | None:
        """Consume one firing of ``name``; returns its parameters, or None if not armed."""
        with self._lock:
            armed = self._armed.get(name)
            if armed is None:
                return None
            armed.fired += 1
            self.history.append(name)
            if armed.remaining is not None:
                armed.remaining -= 1
                if armed.remaining <= 0:
                    del self._armed[name]
            return dict(armed.params)
