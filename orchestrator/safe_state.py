"""The safe state, verified: commanded, read back and retried until confirmed or out of attempts.

"Instruments safe" used to mean "the safe commands were sent": a reply lost,
a stale reply read as the answer, or nothing listening at all, and the
console still said safe (issue 9). Here an action counts only when a
read-back confirms it — the table's measured rate at rest, the chamber's
setpoint register at the safe value — and what is printed and journaled is
exactly what was read, or, in red, that it was not confirmed and a person
must look.

Before the first safe command each link is reset (closed; the next command
opens a fresh connection), so a reply left in a socket by an exchange cut
short can never be taken for the answer to a safe command. Each action is
attempted the station's ``retries`` times (the driver's own retries of
transient errors run inside each attempt), and a refusal — a Modbus
exception, a table ``ERROR`` reply — is attempted again like any other failure.
"""

from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from typing import Any, TextIO

from gyrocal.instruments.interfaces import Chamber, HoldingTable, PowerSupply, RateTable
from gyrocal.instruments.supply.coil import CoilDrive
from gyrocal.models.clock import Clock

#: A stopped table reads back |rate| at most this (the simulated encoder noise is ~1e-3 deg/s).
TABLE_STOPPED_DPS = 0.01
#: The chamber setpoint register must read back within this of the safe setpoint
#: (half a unit of the last decimal an F4 carries is 0.05).
SETPOINT_MATCH_C = 0.05
#: Clock seconds between rate read-backs of a decelerating table.
POLL_S = 0.5
#: A decelerating table is watched while its rate keeps falling, up to this long in all.
STOP_MAX_S = 900.0
#: ...and given up on when the rate has not fallen for this long.
STOP_STALL_S = 10.0

RED = "\033[31m"
RESET = "\033[0m"


@dataclass(frozen=True)
class SafePolicy:
    """What safe means for one station, and how hard to try."""

    setpoint_c: float | None     # None: the chamber holds its setpoint (station safe_state: hold)
    chamber_attempts: int = 3    # the station's chamber.retries
    table_attempts: int = 3      # the station's table.retries
    #: the unit's supply: "keep_on" or "switch_off" (station supply.safe_state); None: no supply
    unit_power: str | None = None
    supply_attempts: int = 3
    #: hold the table's axis under servo instead of switching it off (station
    #: ``table.orientation: horizontal``: a servo-off axis lets an unbalanced load swing down)
    table_hold: bool = False


@dataclass(frozen=True)
class SafeAction:
    """One instrument's safe action as it ended: confirmed by read-back, or not."""

    instrument: str        # "table" | "chamber"
    confirmed: bool
    text: str              # what the console and the journal say
    attempts: int          # how many attempts it took (or were spent)


#: What the console and the journal say when a run stops before it commanded anything.
NOTHING_COMMANDED = ("nothing was commanded: the instruments are as they were found "
                     "(no safe state was needed)")


@dataclass(frozen=True)
class SafeOutcome:
    actions: tuple[SafeAction, ...]
    #: False when the run stopped before its first command (identify and preflight reads
    #: only): no safe state was commanded, and "NOT CONFIRMED SAFE" would be untrue
    commanded: bool = True

    @classmethod
    def nothing_commanded(cls) -> SafeOutcome:
        return cls((), commanded=False)

    @property
    def confirmed(self) -> bool:
        return all(action.confirmed for action in self.actions)

    def journal_fields(self) -> dict[str, Any]:
        return {"actions": {a.instrument: a.text for a in self.actions},
                "confirmed": {a.instrument: a.confirmed for a in self.actions},
                "attempts": {a.instrument: a.attempts for a in self.actions},
                **({} if self.commanded else {"commanded": False})}

    def summary(self) -> str:
        if not self.commanded:
            return NOTHING_COMMANDED
        if self.confirmed:
            return "instruments safe (confirmed by read-back)"
        return "INSTRUMENTS NOT CONFIRMED SAFE — check them by hand"

    def print(self, stream: TextIO | None = None) -> None:
        stream = stream if stream is not None else sys.stderr
        if not self.commanded:
            print(f"gyrocal: safe state: {NOTHING_COMMANDED}", file=stream, flush=True)
            return
        colour = stream.isatty()
        for action in self.actions:
            text = action.text if action.confirmed or not colour else f"{RED}{action.text}{RESET}"
            print(f"gyrocal: safe state: {text}", file=stream, flush=True)


def _not_confirmed(instrument: str, detail: str, attempts: int) -> SafeAction:
    return SafeAction(instrument, False,
                      f"{instrument.upper()} NOT CONFIRMED SAFE — check it by hand ({detail})",
                      attempts)


def _failure(exc: Exception) -> str:
    return f"{type(exc).__name__}: {exc}"


def _at_rest_dps(table: RateTable, clock: Clock) -> tuple[float | None, str]:
    """Read the rate back until it is at rest (the axis decelerates at its limit): the
    rate at rest, or None and what was last read when it kept moving."""
    started_s = clock.now_s()
    best_dps = float("inf")
    best_s = started_s
    while True:
        rate_dps = float(table.read_rate_dps())
        if abs(rate_dps) <= TABLE_STOPPED_DPS:
            return abs(rate_dps), ""
        now_s = clock.now_s()
        if abs(rate_dps) < best_dps:
            best_dps, best_s = abs(rate_dps), now_s
        if now_s - best_s >= STOP_STALL_S or now_s - started_s >= STOP_MAX_S:
            return None, f"rate reads back {rate_dps:.3f} deg/s after stop"
        clock.sleep(POLL_S)


def table_safe_text(hold: bool) -> str:
    """What the table's safe state does, as ``gyrocal plan`` announces it."""
    if hold:
        return ("table held at rest under servo in position mode, confirmed by read-back of "
                "rest and mode (horizontal axis: servo off would let an unbalanced load swing "
                "down)")
    return "table stopped, then servo off (:Mode:Off), rest confirmed by read-back"


def _hold_once(table: RateTable, clock: Clock) -> tuple[str | None, str]:
    """One attempt at holding: (the confirmation, "") or (None, why not)."""
    if not isinstance(table, HoldingTable):
        return None, f"table driver {type(table).__name__} cannot hold its axis under servo"
    table.hold()
    rest_dps, why = _at_rest_dps(table, clock)
    if rest_dps is None:
        return None, why
    mode = table.read_servo_mode()
    if mode in ("off", "synthesis"):
        return None, f"at rest ({rest_dps:.3f} deg/s) but the servo mode reads back {mode}"
    return (f"table held at rest under servo (horizontal axis; read back {rest_dps:.3f} deg/s, "
            f"mode {mode})"), ""


def stop_table(table: RateTable, clock: Clock, attempts: int, hold: bool = False) -> SafeAction:
    """``stop``, then read the rate back until it is at rest (the axis decelerates at its limit).

    ``hold`` (a horizontal axis): ``hold`` instead of ``stop``, and confirmed only when
    the rate is at rest *and* the servo mode reads back still servoing, never off.
    """
    last = "no answer"
    attempts = max(1, attempts)
    for attempt in range(1, attempts + 1):
        try:
            if hold:
                text, last = _hold_once(table, clock)
                if text is not None:
                    return SafeAction("table", True, text, attempt)
                continue
            table.stop()
            rest_dps, last = _at_rest_dps(table, clock)
            if rest_dps is not None:
                return SafeAction("table", True, f"table stopped (read back {rest_dps:.3f} deg/s)",
                                  attempt)
        except Exception as exc:  # noqa: BLE001 - every failure is attempted again, then reported
            last = _failure(exc)
    return _not_confirmed("table", last, attempts)


def chamber_to_safe(chamber: Chamber, setpoint_c: float | None, clock: Clock,
                    attempts: int) -> SafeAction:
    """Write the safe setpoint and read the setpoint register back until it matches."""
    last = "no answer"
    attempts = max(1, attempts)
    for attempt in range(1, attempts + 1):
        try:
            if setpoint_c is None:   # the station's safe state is "hold the setpoint"
                held_c = float(chamber.read_setpoint_c())
                return SafeAction("chamber", True,
                                  f"chamber holding setpoint {held_c:.1f} °C (read back)", attempt)
            chamber.set_setpoint_c(setpoint_c)
            read_c = float(chamber.read_setpoint_c())
            if abs(read_c - setpoint_c) <= SETPOINT_MATCH_C:
                return SafeAction("chamber", True, f"chamber setpoint {read_c:.1f} °C (read back)",
                                  attempt)
            last = f"setpoint reads back {read_c:.2f} °C, not {setpoint_c:.2f} °C"
        except Exception as exc:  # noqa: BLE001 - every failure is attempted again, then reported
            last = _failure(exc)
        clock.sleep(POLL_S)
    return _not_confirmed("chamber", last, attempts)


def unit_power_to_safe(supply: PowerSupply, action: str, attempts: int) -> SafeAction:
    """``switch_off``: output off, read back off. ``keep_on``: read back that it is still on."""
    last = "no answer"
    attempts = max(1, attempts)
    for attempt in range(1, attempts + 1):
        try:
            if action == "switch_off":
                supply.set_output(False)
            reading = supply.read()
            wanted_on = action == "keep_on"
            if reading.output_on == wanted_on:
                state = (f"kept on (read back {reading.voltage_v:.3f} V, {reading.current_a:.4f} A)"
                         if wanted_on else "switched off (read back: output off)")
                return SafeAction("supply", True, f"unit power {state}", attempt)
            if wanted_on:      # dropped out: never switched back on over a fault
                return _not_confirmed("supply", "the station keeps the unit powered, but the "
                                      "supply output reads off", attempt)
            last = "output still reads on after OUTP off"
        except Exception as exc:  # noqa: BLE001 - every failure is attempted again, then reported
            last = _failure(exc)
    return _not_confirmed("supply", last, attempts)


def coil_to_safe(coil: CoilDrive, attempts: int) -> SafeAction:
    """Both coil channels off, read back off (a field left on would bias the next static)."""
    last = "no answer"
    attempts = max(1, attempts)
    for attempt in range(1, attempts + 1):
        try:
            reading = coil.off()
            if not (reading.positive_on or reading.negative_on):
                return SafeAction("coil", True, "coil switched off (read back: both channels off)",
                                  attempt)
            last = "a coil channel still reads on after OUTP off"
        except Exception as exc:  # noqa: BLE001 - every failure is attempted again, then reported
            last = _failure(exc)
    return _not_confirmed("coil", last, attempts)


def _reset(link: Chamber | RateTable | PowerSupply | CoilDrive) -> None:
    # A link that cannot even close is reported by the action that follows.
    with contextlib.suppress(Exception):
        link.reset_link()


def make_safe(table: RateTable, chamber: Chamber, policy: SafePolicy, clock: Clock,
              supply: PowerSupply | None = None, coil: CoilDrive | None = None) -> SafeOutcome:
    """Fresh links, then the table (it moves the unit), the chamber, the coil, the unit's power;
    each whatever the others did."""
    _reset(table)
    _reset(chamber)
    actions = [stop_table(table, clock, policy.table_attempts, policy.table_hold),
               chamber_to_safe(chamber, policy.setpoint_c, clock, policy.chamber_attempts)]
    if coil is not None:
        _reset(coil)
        actions.append(coil_to_safe(coil, policy.supply_attempts))
    if supply is not None and policy.unit_power is not None:
        _reset(supply)
        actions.append(unit_power_to_safe(supply, policy.unit_power, policy.supply_attempts))
    return SafeOutcome(tuple(actions))
