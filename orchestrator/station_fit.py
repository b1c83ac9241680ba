"""Does this procedure run on this station? One answer for ``validate`` and ``run``.

The adversarial pass found a 250 Hz procedure that validated against a 2000 Hz
station which ``run`` then refused: the check lived in ``run`` alone. Both
commands now call :func:`check_runnable`, so "validate OK" means "run will
start" for the same station and the same ``--sim`` choice. (Limits - rates,
accelerations, ramps, temperatures against the station's - are checked while
the procedure loads, so every command sees them.)
"""

from __future__ import annotations

from gyrocal.errors import BadInput
from gyrocal.orchestrator.procedure import Procedure


def is_simulated(procedure: Procedure) -> bool:
    """Every instrument address of the station is ``sim``: it can only run with ``--sim``."""
    station = procedure.station
    return all(address == "sim" for address in station.addresses().values())


def check_runnable(procedure: Procedure, sim: bool) -> None:
    """Raise :class:`BadInput` naming every reason ``run`` (with or without ``--sim``) would refuse."""
    station = procedure.station
    problems: list[str] = []
    if not sim:
        sim_addresses = [name for name, address in station.addresses().items() if address == "sim"]
        if sim_addresses:
            problems.append(f"{station.file}: {', '.join(sim_addresses)}: 'sim' needs --sim "
                            "(or a station file with real addresses)")
        fs_hz = procedure.defaults.sample_rate_hz
        if abs(fs_hz - station.gyro.sample_rate_hz) > 1e-9:
            problems.append(
                f"{procedure.file}: defaults.sample_rate_hz: {fs_hz:g} Hz, but the gyro of station "
                f"{station.file} is configured for {station.gyro.sample_rate_hz:g} Hz "
                "(gyro.sample_rate_hz); a STIM300 streams at its configured rate, so set the "
                "procedure to it or reconfigure the unit (with --sim the simulated gyro takes the "
                "procedure's rate)")
    if problems:
        raise BadInput("\n".join(problems))
