"""Telling people when a run needs them: station ``notify:`` targets, sent with apprise.

Nobody watches a terminal at 3 a.m. A station file lists who is told what::

    notify:
      - url: mailto://smtp.lab.example:25?from=gyrocal@lab.example&to=oncall@lab.example
        on: [faulted, needs_operator]
      - url: json://ops.lab.example:8080/gyrocal        # a webhook (HTTP POST of JSON)
        on: [finished, faulted, paused]
      - command: [/usr/local/bin/page-oncall, --quiet]  # gets EVENT and the message as arguments
        on: [faulted]

``url`` is any apprise URL (e-mail over SMTP, JSON/form webhooks, chat
services…), so no protocol client is written here. The triggers are journal
events (:data:`TRIGGERS`); every attempt is journaled as ``notified`` with its
outcome, and a failure is journaled and otherwise ignored: a notification
never stops or faults a run.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any
from urllib.parse import urlsplit

import apprise

from gyrocal.problems import KeyPath
from gyrocal.record.journal import JournalEvent


class NotifyOn(str, Enum):
    FINISHED = "finished"
    FAULTED = "faulted"
    PAUSED = "paused"
    NEEDS_OPERATOR = "needs_operator"


#: Journal event → what it means to the people told. ``operator_needed`` is the event
#: for a step that waits on a person (remount); the engine journals it when it asks.
TRIGGERS: dict[str, NotifyOn] = {
    JournalEvent.RUN_COMPLETED: NotifyOn.FINISHED,
    JournalEvent.FAULT: NotifyOn.FAULTED,
    JournalEvent.INTERRUPTED: NotifyOn.FAULTED,
    JournalEvent.PAUSED: NotifyOn.PAUSED,
    JournalEvent.OPERATOR_NEEDED: NotifyOn.NEEDS_OPERATOR,
}
COMMAND_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class NotifyTarget:
    on: frozenset[NotifyOn]
    url: str | None = None               # an apprise URL
    command: tuple[str, ...] | None = None

    def describe(self) -> str:
        """For the journal: the scheme and host, never a password inside the URL."""
        if self.command:
            return f"command {self.command[0]}"
        parts = urlsplit(self.url or "")
        return f"{parts.scheme}://{parts.netloc.rpartition('@')[2]}"


def parse_notify(report: Callable[[KeyPath, str], None], where: KeyPath, value: object
                 ) -> tuple[NotifyTarget, ...]:
    """The station's ``notify:`` list; problems go to ``report`` with their key path."""
    if not isinstance(value, list):
        report(where, "notify must be a list of targets (each with url: or command:, and on:)")
        return ()
    targets = []
    names = ", ".join(n.value for n in NotifyOn)
    for index, item in enumerate(value):
        at = (*where, index)
        if not isinstance(item, dict):
            report(at, "a notify target is a mapping with url: or command:, and on:")
            continue
        unknown = sorted(set(item) - {"url", "command", "on"})
        if unknown:
            report((*at, unknown[0]), f"unknown key {unknown[0]!r} (url, command, on)")
        url, command = item.get("url"), item.get("command")
        if (url is None) == (command is None):
            report(at, "give exactly one of url: (an apprise URL) or command: (a list)")
            continue
        if url is not None and not (isinstance(url, str) and "://" in url):
            report((*at, "url"), "url must be an apprise URL such as mailto://host:25?to=… "
                   "or json://host:port/path")
            continue
        if command is not None and not (isinstance(command, list) and command
                                        and all(isinstance(c, str) for c in command)):
            report((*at, "command"), "command must be a non-empty list of strings")
            continue
        on = item.get("on", [n.value for n in NotifyOn])
        if not isinstance(on, list) or not all(isinstance(o, str) for o in on) or not on:
            report((*at, "on"), f"on must be a list of events: {names}")
            continue
        bad = [o for o in on if o not in {n.value for n in NotifyOn}]
        if bad:
            report((*at, "on"), f"unknown event {bad[0]!r}; events are {names}")
            continue
        targets.append(NotifyTarget(frozenset(NotifyOn(o) for o in on), url,
                                    tuple(command) if command else None))
    return tuple(targets)


def _send(target: NotifyTarget, what: NotifyOn, title: str, body: str) -> str | None:
    """Send one notification; None when sent, else why not (never raises)."""
    try:
        if target.command:
            done = subprocess.run([*target.command, what.value, body], capture_output=True,
                                  text=True, timeout=COMMAND_TIMEOUT_S, check=False)
            return None if done.returncode == 0 else (
                f"exit {done.returncode}: {(done.stderr or done.stdout).strip()[:200]}")

        sender = apprise.Apprise()
        if not sender.add(target.url):
            return "apprise does not understand this URL"
        with apprise.LogCapture(level=apprise.logging.WARNING) as log:
            ok = sender.notify(title=title, body=body)
            return None if ok else (log.getvalue().strip().splitlines() or ["not sent"])[-1]
    except Exception as exc:  # noqa: BLE001 - a notification never stops a run
        return f"{type(exc).__name__}: {exc}"


class Notifier:
    """Watches the events a journal writes and tells each target what it asked for."""

    def __init__(self, targets: tuple[NotifyTarget, ...], run_label: str) -> None:
        self.targets = targets
        self.run_label = run_label

    def attach(self, journal: Any) -> None:
        """Send after each triggering event is durably journaled, and journal the outcome."""
        if not self.targets:
            return

        def on_event(event: dict[str, Any]) -> None:
            what = TRIGGERS.get(str(event.get("event")))
            if what is None:
                return
            for target in self.targets:
                if what in target.on:
                    error = _send(target, what, *self.message(what, event))
                    journal.append(JournalEvent.NOTIFIED, on=what.value, target=target.describe(),
                                   ok=error is None, error=error)

        journal.listeners.append(on_event)

    def message(self, what: NotifyOn, event: dict[str, Any]) -> tuple[str, str]:
        title = f"gyrocal {self.run_label}: {what.value.replace('_', ' ')}"
        parts = [f"event {event.get('event')} (journal #{event.get('seq')})"]
        step = event.get("step_id") or event.get("before_step")
        if step:
            parts.append(f"step {step}")
        if event.get("message"):
            parts.append(str(event["message"]))
        return title, "; ".join(parts)
