"""The unit under test's power: switched on at connect, read back and journaled per logged step.

A gyro's output depends on its supply (IEEE Std 952 test set-ups power it from
a programmable supply and log its current), and a unit drawing its supply's
limit, or a supply that has dropped out, is not calibrating anything: both are
faults, handled like a chamber alarm — the safe state, exit 3, resumable.
What the safe state does with the power is the station's choice
(``supply.safe_state.unit_power``): ``keep_on`` preserves the unit's thermal
state for a resume, ``switch_off`` protects a unit that must not run unattended.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.instruments.errors import InstrumentSafetyError
from gyrocal.instruments.interfaces import PowerSupply, SupplyReading
from gyrocal.record.journal import JournalEvent

#: a current at or above this fraction of the limit: the supply is limiting (over-current)
AT_LIMIT_FRACTION = 0.98
#: an output voltage below this fraction of the set voltage: the supply is not holding it
SAG_FRACTION = 0.95


@dataclass(frozen=True)
class UnitPowerPolicy:
    voltage_v: float
    current_limit_a: float
    safe_action: str          # "keep_on" | "switch_off"
    attempts: int = 3         # station supply.retries, for the safe action


def judge(reading: SupplyReading, policy: UnitPowerPolicy) -> str | None:
    """Why ``reading`` is a fault, or None when the unit is powered as declared."""
    if not reading.output_on:
        return "the supply output is off (it dropped out)"
    if reading.current_a >= AT_LIMIT_FRACTION * policy.current_limit_a:
        return (f"over-current: the unit draws {reading.current_a:.4g} A at the supply's "
                f"{policy.current_limit_a:g} A limit")
    if reading.voltage_v < SAG_FRACTION * policy.voltage_v:
        return (f"the supply holds {reading.voltage_v:.4g} V, not {policy.voltage_v:g} V "
                "(dropping out or limiting)")
    return None


def _fields(reading: SupplyReading) -> dict[str, object]:
    return {"voltage_v": reading.voltage_v, "current_a": reading.current_a,
            "output_on": reading.output_on}


def power_on(supply: PowerSupply, policy: UnitPowerPolicy, journal) -> SupplyReading:
    """Set level and limit (read back), switch on, read and judge; journaled as ``supply_read``."""
    supply.configure(policy.voltage_v, policy.current_limit_a)
    supply.set_output(True)
    return check(supply, policy, journal, when="power_on")


def check(supply: PowerSupply, policy: UnitPowerPolicy, journal, when: str,
          step_id: str | None = None) -> SupplyReading:
    """Read the supply, journal what it read, raise a safety fault if the unit is not powered right."""
    reading = supply.read()
    problem = judge(reading, policy)
    journal.append(JournalEvent.SUPPLY_READ, when=when, step_id=step_id, ok=problem is None,
                   **_fields(reading))
    if problem is not None:
        raise InstrumentSafetyError(supply.name, "read back", problem)
    return reading
