"""Faults a dry run injects on purpose, from ``gyrocal run --sim --inject SPEC``.

A lab engineer rehearses what the night will do when the chamber stops
answering or the interlock opens, against the simulators, before trusting it
with hardware. A spec names the instrument, the fault (the simulator's own
names, see each simulator's ``FAULTS``), how many requests it lasts and the
plan step before which it is armed:

    chamber.no_reply                 the next request to the chamber gets no reply
    chamber.no_reply:5@T02.soak      five unanswered requests, from step T02.soak on
    table.interlock_open:always@T01.sf.+50dps
    gyro.lose_frames:40              40 frames lost from the start
    table.late_reply:1:delay_s=2     parameters as key=value after the count
    fixture.wrong_mount@T01.MY.remount   the simulated fixture turns to the wrong face

``always`` arms it until the run ends. Every fault armed is journaled
(``fault_injected``), so the audit trail says which troubles were deliberate.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

_SPEC = re.compile(
    r"^(?P<role>[a-z_]+)\.(?P<fault>[a-z_]+)"
    r"(?::(?P<count>always|\d+))?(?P<params>(?::[a-z_]+=[^:@]+)*)(?:@(?P<step>\S+))?$"
)


class FaultSpecError(ValueError):
    """A ``--inject`` value that does not parse or names an unknown fault."""


@dataclass(frozen=True)
class FaultInjection:
    role: str
    fault: str
    count: int | None                 # None = until the run ends
    params: dict[str, Any] = field(default_factory=dict)
    before_step: str | None = None    # None = from the start

    @property
    def text(self) -> str:
        count = "always" if self.count is None else str(self.count)
        params = "".join(f":{k}={v}" for k, v in self.params.items())
        step = f"@{self.before_step}" if self.before_step else ""
        return f"{self.role}.{self.fault}:{count}{params}{step}"


def _value(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text


def parse_injection(spec: str, known: dict[str, tuple[str, ...]]) -> FaultInjection:
    """Parse one ``--inject`` value; ``known`` maps role → the simulator's FAULTS."""
    match = _SPEC.match(spec.strip())
    if match is None:
        raise FaultSpecError(
            f"--inject {spec!r}: expected ROLE.FAULT[:COUNT|:always][:key=value…][@STEP], "
            "e.g. chamber.no_reply:3@T02.soak")
    role, fault = match["role"], match["fault"]
    if role not in known:
        raise FaultSpecError(f"--inject {spec!r}: this station has no simulated {role!r}; "
                             f"it has: {', '.join(known)}")
    if fault not in known[role]:
        raise FaultSpecError(f"--inject {spec!r}: the simulated {role} has no fault {fault!r}; "
                             f"it knows: {', '.join(known[role])}")
    count_text = match["count"] or "1"
    count = None if count_text == "always" else int(count_text)
    if count == 0:
        raise FaultSpecError(f"--inject {spec!r}: a count must be at least 1 (or 'always')")
    params = {}
    for item in filter(None, (match["params"] or "").split(":")):
        key, _, value = item.partition("=")
        params[key] = _value(value)
    return FaultInjection(role, fault, count, params, match["step"])


class FaultPlan:
    """Arms the parsed injections on a simulated station as the run reaches their steps."""

    def __init__(self, injections: list[FaultInjection]) -> None:
        self.injections = list(injections)
        self._armed: set[int] = set()

    def check_steps(self, step_ids: list[str]) -> None:
        """Refuse an injection that names a step the plan does not have (before anything moves)."""
        for injection in self.injections:
            if injection.before_step and injection.before_step not in step_ids:
                raise FaultSpecError(
                    f"--inject {injection.text!r}: the plan has no step {injection.before_step!r}; "
                    f"see `gyrocal plan` for the step ids")

    def arm_due(self, simulated, step_id: str | None) -> list[FaultInjection]:
        """Arm every injection whose step has come (``step_id`` None: the ones from the start).

        Returns what was armed, for the run to journal (``fault_injected``): the run record
        is the orchestrator's, not the simulators'.
        """
        injectors = {"chamber": simulated.chamber_faults, "table": simulated.table_faults,
                     "gyro": simulated.gyro_faults, "fixture": simulated.fixture_faults,
                     "supply": simulated.supply_faults}
        armed = []
        for index, injection in enumerate(self.injections):
            if index in self._armed or injection.before_step not in (None, step_id):
                continue
            injectors[injection.role].arm(injection.fault, count=injection.count,
                                          **injection.params)
            self._armed.add(index)
            armed.append(injection)
        return armed
