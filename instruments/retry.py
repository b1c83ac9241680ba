"""Bounded retries with backoff for transient instrument faults.

Retries are finite and every attempt is reported through ``on_retry`` so the
orchestrator can journal it; nothing is retried silently.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from gyrocal.instruments.errors import InstrumentError

T = TypeVar("T")


@dataclass(frozen=True)
class RetryPolicy:
    attempts: int = 3
    backoff_s: float = 0.05
    backoff_factor: float = 2.0

    def __post_init__(self) -> None:
        if self.attempts < 1:
            raise ValueError("attempts must be >= 1")


def call_with_retry(
    func: Callable[[], T],
    policy: RetryPolicy,
    on_retry: Callable[[int, InstrumentError], None] | None = None,
    before_retry: Callable[[], None] | None = None,
    sleep: Callable[[float], None] = time.sleep,
) -> T:
    """Call ``func``; on a transient :class:`InstrumentError` wait and try again.

    Non-transient errors propagate at once. After the last attempt the last
    error propagates. ``before_retry`` (e.g. reconnect) runs before each retry.
    ``sleep`` is wall-clock: backoff protects a real serial line or socket,
    so it is not simulated time.
    """
    delay = policy.backoff_s
    for attempt in range(1, policy.attempts + 1):
        try:
            return func()
        except InstrumentError as exc:
            if not exc.transient or attempt == policy.attempts:
                raise
            if on_retry is not None:
                on_retry(attempt, exc)
            sleep(delay)
            delay *= policy.backoff_factor
            if before_retry is not None:
                before_retry()
    raise AssertionError("unreachable")
