"""``gyrocal station check``: connect to each instrument, move nothing, report what a run relies on.

What a lab runs when it first connects real instruments. Only queries are
sent: the chamber's registers are read (never written), the table is asked
(``*IDN?``, ``:Interlock?``, ``:Mode?``, ``:Read:Rate?`` …; the driver takes
remote lockout only before a change, so not here), the gyro is listened to.
Every fact a run relies on is printed (and written with ``--json``); anything
that would stop or endanger a run is a *problem*, named with its instrument,
and the command exits 3. An instrument that does not answer is a problem of
its own; the other instruments are still checked.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrocal.app.library_logs import quiet_library_logs
from gyrocal.errors import EXIT_FAULT, EXIT_OK, BadInput
from gyrocal.instruments.errors import InstrumentConnectionError, InstrumentError, InstrumentTimeout
from gyrocal.instruments.factory import open_chamber, open_gyro, open_supply, open_table
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.interfaces import Chamber, GyroStream, PowerSupply, ReportsUnits
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.instruments.table.acutrol_protocol import InterlockState, TableMode
from gyrocal.orchestrator.gyro_check import check_gyro_stream
from gyrocal.orchestrator.station import (
    ChamberConfig,
    Station,
    SupplyConfig,
    TableConfig,
    load_station,
)
from gyrocal.orchestrator.unit_power import UnitPowerPolicy, judge

ROLES = ("chamber", "table", "gyro", "supply")
#: Faster than this, the table is turning: a run would take over a moving table.
TABLE_AT_REST_DPS = 0.05
#: Below absolute zero, or hotter than any calibration chamber: not a temperature.
PLAUSIBLE_C = (-273.15, 500.0)


@dataclass
class RoleCheck:
    """What one instrument reported, and what of it would stop a run."""

    role: str
    driver: str
    address: str
    facts: dict[str, Any] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def check_chamber(chamber: Chamber, config: ChamberConfig) -> RoleCheck:
    result = RoleCheck("chamber", config.driver, config.address)
    facts = result.facts
    facts["identity"] = chamber.identify().description
    if isinstance(chamber, ReportsUnits):
        units = chamber.read_units()
        facts["units"] = "°F" if units.fahrenheit else "°C"
        facts["decimals"] = units.decimals
        facts["units_source"] = units.source
    status = chamber.read_status()
    facts["process_value_c"] = round(status.temperature_c, 3)
    facts["setpoint_c"] = round(status.setpoint_c, 3)
    facts["alarm"] = status.alarm
    facts["alarm_detail"] = status.detail
    facts["profile_running"] = status.profile_running
    facts["run_state"] = status.run_state
    if config.driver == "watlow_f4":
        facts["limit_input"] = config.limit_input
    if status.alarm:
        result.problems.append(f"alarm active ({status.detail or 'no detail'})")
    if status.profile_running:
        result.problems.append(f"the controller runs its own profile ({status.run_state}); "
                               "a run would refuse to start")
    lo, hi = config.limits.min_temp_c, config.limits.max_temp_c
    for name, value in (("process value", status.temperature_c), ("set point", status.setpoint_c)):
        if not (math.isfinite(value) and PLAUSIBLE_C[0] <= value <= PLAUSIBLE_C[1]):
            result.problems.append(f"{name} {value:g} °C is not a plausible temperature "
                                   "(units or decimals wrong?)")
        elif not lo <= value <= hi:
            result.problems.append(f"{name} {value:.2f} °C outside the station's limits "
                                   f"{lo:g}..{hi:g} °C")
    return result


def check_table(table: Acutrol3000Table, config: TableConfig) -> RoleCheck:
    result = RoleCheck("table", config.driver, config.address)
    facts = result.facts
    facts["identity"] = table.identify().description
    interlock = table.interlock_state()
    mode = table.read_mode()
    rate_dps = table.read_rate_dps()
    facts["interlock"] = interlock.value
    facts["mode"] = mode.name.lower()
    facts["rate_dps"] = rate_dps
    facts["position_deg"] = table.read_position_deg()
    facts["acceleration_limit_dps2"] = table.read_acceleration_limit_dps2()
    if interlock is InterlockState.FAULT:
        result.problems.append("interlock fault: clear its cause, a run cannot close it")
    if abs(rate_dps) > TABLE_AT_REST_DPS:
        result.problems.append(f"the table is turning ({rate_dps:+.3f} deg/s, mode "
                               f"{mode.name.lower()}); a run would take over a moving table")
    if abs(rate_dps) > config.limits.max_rate_dps:
        result.problems.append(f"rate {rate_dps:+.3f} deg/s beyond the station's limit "
                               f"{config.limits.max_rate_dps:g} deg/s")
    if mode not in (TableMode.OFF, TableMode.RATE, TableMode.POSITION):
        result.problems.append(f"the axis is in {mode.name.lower()} mode")
    return result


def _checked(role: str, driver: str, address: str, work: Callable[[], RoleCheck]) -> RoleCheck:
    """Run one role's check; an instrument fault becomes that role's problem, never a traceback."""
    try:
        return work()
    except InstrumentError as exc:
        result = RoleCheck(role, driver, address)
        silent = isinstance(exc, (InstrumentConnectionError, InstrumentTimeout))
        result.problems.append(f"no usable answer: {exc}" if silent else str(exc))
        return result


def run_checks(station: Station, roles: tuple[str, ...]) -> list[RoleCheck]:
    results = []
    if "chamber" in roles:
        c = station.chamber

        def chamber_work() -> RoleCheck:
            driver = open_chamber(c, c.address)
            try:
                return check_chamber(driver, c)
            finally:
                driver.close()
        results.append(_checked("chamber", c.driver, c.address, chamber_work))
    if "table" in roles:
        t = station.table

        def table_work() -> RoleCheck:
            with open_table(t, t.address) as driver:
                return check_table(driver, t)
        results.append(_checked("table", t.driver, t.address, table_work))
    if "gyro" in roles:
        g = station.gyro

        def gyro_work() -> RoleCheck:
            result = RoleCheck("gyro", g.driver, g.port)
            driver = open_gyro(g, g.port)
            try:
                check = check_gyro_stream if isinstance(driver, Stim300Gyro) else check_timed_stream
                facts, problems = check(driver, g.sample_rate_hz)
            finally:
                driver.close()
            result.facts.update(facts)
            result.problems.extend(problems)
            return result
        results.append(_checked("gyro", g.driver, g.port, gyro_work))
    s = station.supply
    if "supply" in roles and s is not None:

        def supply_work() -> RoleCheck:
            driver = open_supply(s, s.address)
            try:
                return check_supply(driver, s)
            finally:
                driver.close()
        results.append(_checked("supply", s.driver, s.address, supply_work))
    return results


def check_timed_stream(gyro: GyroStream, sample_rate_hz: float) -> tuple[dict[str, Any], list[str]]:
    """A DMM or counter input chain: identity, then half a second of readings (nothing set but
    the stream itself, which every run restarts)."""
    facts: dict[str, Any] = {"identity": gyro.identify().description}
    gyro.flush()
    block = gyro.read_samples(max(10, int(round(sample_rate_hz * 0.5))), timeout_s=3.0)
    facts.update(readings=len(block), bad_readings=block.flagged_count,
                 mean_output=float(np.mean(block.rate)) if len(block) else None)
    problems = [f"{block.flagged_count} of {len(block)} readings overloaded or flagged"
                ] if block.flagged_count else []
    return facts, problems


def check_supply(supply: PowerSupply, config: SupplyConfig) -> RoleCheck:
    """Identity and what the supply reads now; it is never switched (a run powers the unit)."""
    result = RoleCheck("supply", config.driver, config.address)
    reading = supply.read()
    result.facts.update(identity=supply.identify().description, output_on=reading.output_on,
                        voltage_v=reading.voltage_v, current_a=reading.current_a)
    if reading.output_on:
        policy = UnitPowerPolicy(config.voltage_v, config.current_limit_a, config.unit_power_safe)
        problem = judge(reading, policy)
        if problem is not None:
            result.problems.append(problem)
    return result


def _print(results: list[RoleCheck]) -> None:
    for result in results:
        verdict = "ok" if result.ok else f"{len(result.problems)} problem(s)"
        print(f"{result.role} ({result.driver} at {result.address}): {verdict}")
        for key, value in result.facts.items():
            print(f"  {key}: {value}")
        for problem in result.problems:
            print(f"  PROBLEM: {problem}")


def cmd_station_check(args: argparse.Namespace) -> int:
    quiet_library_logs(getattr(args, "debug", False))
    station = load_station(args.station)
    roles = (args.only,) if args.only else ROLES
    addresses = {key.split(".")[0]: address for key, address in station.addresses().items()}
    roles = tuple(role for role in roles if role in addresses)
    simulated = [role for role in roles if addresses[role] == "sim"]
    if simulated:
        raise BadInput(f"{args.station}: {', '.join(simulated)} address 'sim'; check a live station "
                       "(e.g. the file `gyrocal sim serve --write-station` writes)")
    results = run_checks(station, roles)
    _print(results)
    problems = [f"{r.role}: {p}" for r in results for p in r.problems]
    if args.json:
        document = {"station": str(args.station), "ok": not problems, "problems": problems,
                    "instruments": {r.role: {**asdict(r), "ok": r.ok} for r in results}}
        Path(args.json).write_text(json.dumps(document, indent=2, ensure_ascii=False) + "\n",
                                   encoding="utf-8")
    if problems:
        print(f"station check: {len(problems)} problem(s):", file=sys.stderr)
        for problem in problems:
            print(f"  {problem}", file=sys.stderr)
        return EXIT_FAULT
    print("station check: every instrument fit for a run")
    return EXIT_OK
