"""Decision rules and the run's overall verdict: the one owner of PASS / FAIL / CONDITIONAL.

A calibration lab states how it decides conformity when a measured value has
an uncertainty (ISO/IEC 17025 §7.8.6, ILAC-G8:09/2019, JCGM 106:2012):

* ``simple`` (the default, as before this module existed): the value alone
  is compared with the limit; the measurement uncertainty is stated beside it
  and the risk of a false accept may be up to 50 % at the limit;
* ``guarded`` (ILAC-G8 guarded acceptance with guard band w = U, ISO 14253-1):
  PASS only if the whole interval value ± U is inside the limit, FAIL only if it
  is wholly outside, otherwise CONDITIONAL ("conformity indeterminate").

The overall verdict, in order of precedence: INVALID (physics checks:
sanity.py) > FAIL (any limit failed) > BLOCKED (a reference instrument whose
calibration was due before the run, unless the station waives it with a
reason; or an identity the instrument reported that differs from the
station's declared one) > INCOMPLETE (a limit NOT EVALUATED: the step its
metric needs never completed, or a noise term the record cannot identify) >
CONDITIONAL (any guarded limit indeterminate) > PASS. Only PASS exits 0.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any, Protocol

from gyrocal.instruments.identity import reported_serial


class Check(Protocol):
    """A physics check's outcome (sanity.SanityCheck; sanity.py imports this module)."""

    name: str
    ok: bool
    detail: str


class DecisionRule(str, Enum):
    SIMPLE = "simple"
    GUARDED = "guarded"


class Decision(str, Enum):
    PASS = "PASS"
    FAIL = "FAIL"
    CONDITIONAL = "CONDITIONAL"
    #: the step the metric needs was not completed (an interrupted run's rebuilt report),
    #: or the metric is a noise term this record cannot identify and its upper bound
    #: does not settle the limit: nothing was measured to judge
    NOT_EVALUATED = "NOT EVALUATED"


DEFAULT_RULE = DecisionRule.SIMPLE


def decide(value: float, expanded_u: float | None, limit: float, kind: str,
           rule: DecisionRule) -> tuple[Decision, float]:
    """One limit's decision and the guard band used (0 under the simple rule).

    ``kind`` is "max" (value ≤ limit conforms) or "min" (value ≥ limit).
    Under the guarded rule a missing U cannot be guarded: CONDITIONAL.
    """
    if kind not in ("max", "min"):
        raise ValueError(f"limit kind must be max or min, got {kind!r}")
    sign = 1.0 if kind == "max" else -1.0
    margin = sign * (limit - value)          # > 0: inside the limit
    if rule is DecisionRule.SIMPLE:
        return (Decision.PASS if margin >= 0 else Decision.FAIL), 0.0
    if expanded_u is None:
        return Decision.CONDITIONAL, float("nan")
    guard = abs(expanded_u)
    if margin >= guard:
        return Decision.PASS, guard
    if margin < -guard:
        return Decision.FAIL, guard
    return Decision.CONDITIONAL, guard


class Judged(Protocol):
    """An acceptance limit's outcome (acceptance.AcceptanceVerdict; it imports this module)."""

    name: str
    decision: Decision


@dataclass(frozen=True)
class Blocker:
    """Why a run whose limits all pass still cannot be called PASS."""

    role: str
    reason: str


class Verdict(str, Enum):
    """The run's overall statement of conformity, in order of precedence."""

    INVALID = "INVALID"
    FAIL = "FAIL"
    BLOCKED = "BLOCKED"
    INCOMPLETE = "INCOMPLETE"
    CONDITIONAL = "CONDITIONAL"
    PASS = "PASS"


@dataclass(frozen=True)
class IdentityCheck:
    """What the decision found about one instrument: a waived overdue calibration, the serial
    it reported and whether that differs from the station's declared one."""

    waived: str | None
    reported_serial: str | None
    identity_mismatch: bool

    def to_json(self) -> dict[str, Any]:
        """The keys results.json adds to the instrument's entry (``waived`` only when waived)."""
        out: dict[str, Any] = {} if self.waived is None else {"waived": self.waived}
        return out | {"reported_serial": self.reported_serial,
                      "identity_mismatch": self.identity_mismatch}


@dataclass(frozen=True)
class InstrumentFindings:
    checks: Mapping[str, IdentityCheck]      # role → what was found
    blockers: tuple[Blocker, ...]


def instrument_findings(instruments: Mapping[str, Mapping[str, Any]]) -> InstrumentFindings:
    """Overdue reference calibrations (unless waived) and declared-vs-reported serial mismatches.

    ``instruments`` is results.json's ``instruments`` section (role → entry); it is
    left as it is: what was found is returned beside it.
    """
    blockers = []
    checks = {}
    for role, entry in sorted(instruments.items()):
        waived = None
        if entry.get("calibration_overdue"):
            waiver = entry.get("calibration_waiver")
            if waiver:
                waived = f"calibration overdue, waived by the station: {waiver}"
            else:
                blockers.append(Blocker(role, "reference instrument out of calibration "
                                              f"(due {entry.get('calibration_due')})"))
        # the gyro's declared serial is the procedure's unit under test; a unit that says its
        # own (a STIM300's I<CR>, TS1524 §8.2) is checked against it like any instrument
        reported = reported_serial(entry.get("description"))
        declared = entry.get("serial")
        mismatch = bool(reported and declared and reported.strip().upper()
                        != str(declared).strip().upper())
        if mismatch:
            blockers.append(Blocker(role, f"identity mismatch: the station declares serial "
                                          f"{declared!r}, the instrument reported {reported!r}"))
        checks[role] = IdentityCheck(waived, reported, mismatch)
    return InstrumentFindings(checks, tuple(blockers))


def instrument_blockers(instruments: Mapping[str, Mapping[str, Any]]) -> list[Blocker]:
    """What keeps a run from PASS among its instruments (:func:`instrument_findings`)."""
    return list(instrument_findings(instruments).blockers)


@dataclass(frozen=True)
class SanityLine:
    """One physics check as the verdict states it."""

    name: str
    ok: bool
    detail: str


@dataclass(frozen=True)
class OverallVerdict:
    """results.json ``verdict``: the overall statement and every reason for it."""

    overall: Verdict
    invalid_because: tuple[str, ...]
    blocked_because: tuple[str, ...]
    conditional: tuple[str, ...]
    not_evaluated: tuple[str, ...]
    sanity: tuple[SanityLine, ...]

    def to_json(self) -> dict[str, Any]:
        return {"overall": self.overall.value, "invalid_because": list(self.invalid_because),
                "blocked_because": list(self.blocked_because),
                "conditional": list(self.conditional), "not_evaluated": list(self.not_evaluated),
                "sanity": [{"name": c.name, "ok": c.ok, "detail": c.detail} for c in self.sanity]}


def _overall(failed: bool, decisions: set[Decision], blocked: bool) -> Verdict:
    if failed:
        return Verdict.INVALID
    if Decision.FAIL in decisions:
        return Verdict.FAIL
    if blocked:
        return Verdict.BLOCKED
    if Decision.NOT_EVALUATED in decisions:
        return Verdict.INCOMPLETE
    if Decision.CONDITIONAL in decisions:
        return Verdict.CONDITIONAL
    return Verdict.PASS


def overall_verdict(checks: Sequence[Check], acceptance: Sequence[Judged],
                    blockers: Sequence[Blocker]) -> OverallVerdict:
    """INVALID > FAIL > BLOCKED > INCOMPLETE > CONDITIONAL > PASS, with every reason named."""
    failed = [c for c in checks if not c.ok]
    return OverallVerdict(
        _overall(bool(failed), {a.decision for a in acceptance}, bool(blockers)),
        tuple(f"{c.name}: {c.detail}" for c in failed),
        tuple(f"{b.role}: {b.reason}" for b in blockers),
        tuple(sorted(a.name for a in acceptance if a.decision is Decision.CONDITIONAL)),
        tuple(sorted(a.name for a in acceptance if a.decision is Decision.NOT_EVALUATED)),
        tuple(SanityLine(c.name, c.ok, c.detail) for c in checks))
