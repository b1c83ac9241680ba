"""The run's state machine: which moves are legal, in one declaration.

The engine (``orchestrator/engine.py``) decides *what* to do next from the
plan; this machine only says whether that move is legal from where the run
stands, so an engine bug surfaces as a loud ``MachineError`` instead of a
table spinning during a soak. Built with ``transitions``
(``auto_transitions=False``: no implicit ``to_<state>`` shortcuts; no
callbacks that could swallow exceptions). ``docs/state-machine.md`` is drawn
from this table by :func:`mermaid_diagram`.
"""

from __future__ import annotations

from transitions import Machine, MachineError

__all__ = ["RunStateMachine", "MachineError", "STATES", "TRANSITIONS", "mermaid_diagram"]

#: Written-down order of events: connect, identify, preflight, then per plan step
#: ramp → soak, or spin → settle → log, and finally analyse → report → done.
STATES = (
    "idle",          # nothing connected yet
    "connecting",    # opening transports, *IDN? and identity registers
    "preflight",     # limits, interlock, chamber alarm, gyro stream alive
    "ready",         # between plan steps: instruments idle at known conditions
    "ramping",       # chamber moving to a new setpoint
    "soaking",       # waiting for temperature to stay within tolerance for the hold time
    "spinning",      # table accelerating to a new rate (up or down)
    "settling",      # rate reached, waiting for transients to die out
    "logging",       # recording gyro samples for a step
    "paused",        # operator pause: table stopped, chamber held
    "safing",        # bringing instruments to the safe state after a fault or interrupt
    "faulted",       # safe, stopped, resumable with `gyrocal resume`
    "analysing",     # computing results from the recorded samples
    "reporting",     # writing report/
    "done",
)

_ACTIVE = ["connecting", "preflight", "ready", "ramping", "soaking", "spinning", "settling",
           "logging", "paused", "analysing", "reporting"]

TRANSITIONS: tuple[dict, ...] = (
    {"trigger": "connect", "source": "idle", "dest": "connecting"},
    {"trigger": "identified", "source": "connecting", "dest": "preflight"},
    {"trigger": "preflight_ok", "source": "preflight", "dest": "ready"},
    {"trigger": "ramp", "source": "ready", "dest": "ramping"},
    {"trigger": "soak", "source": "ramping", "dest": "soaking"},
    {"trigger": "stable", "source": "soaking", "dest": "ready"},
    {"trigger": "spin", "source": "ready", "dest": "spinning"},
    {"trigger": "settle", "source": "spinning", "dest": "settling"},
    {"trigger": "settled", "source": ["settling", "spinning"], "dest": "ready"},
    {"trigger": "log", "source": ["ready", "settling"], "dest": "logging"},
    {"trigger": "logged", "source": "logging", "dest": "ready"},
    {"trigger": "pause", "source": ["ready", "ramping", "soaking", "spinning", "settling", "logging"],
     "dest": "paused"},
    {"trigger": "unpause", "source": "paused", "dest": "ready"},
    {"trigger": "fault", "source": _ACTIVE, "dest": "safing"},
    {"trigger": "safed", "source": "safing", "dest": "faulted"},
    {"trigger": "analyse", "source": "ready", "dest": "analysing"},
    {"trigger": "report", "source": "analysing", "dest": "reporting"},
    {"trigger": "finish", "source": "reporting", "dest": "done"},
)


class RunStateMachine:
    """Holds ``state``; triggers are methods (``machine.ramp()``) that raise on illegal moves."""

    state: str

    def __init__(self, initial: str = "idle") -> None:
        self.machine = Machine(
            model=self,
            states=list(STATES),
            transitions=[dict(t) for t in TRANSITIONS],
            initial=initial,
            auto_transitions=False,
            ignore_invalid_triggers=False,
            send_event=False,
        )

    def can(self, trigger: str) -> bool:
        return trigger in self.machine.get_triggers(self.state)


def mermaid_diagram() -> str:
    """The state diagram as Mermaid text (rendered in docs/state-machine.md)."""
    lines = ["stateDiagram-v2", "    [*] --> idle"]
    for transition in TRANSITIONS:
        sources = transition["source"]
        for source in [sources] if isinstance(sources, str) else sources:
            lines.append(f"    {source} --> {transition['dest']}: {transition['trigger']}")
    lines.append("    done --> [*]")
    return "\n".join(lines) + "\n"
