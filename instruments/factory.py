"""Build the drivers a station file names, at the addresses it gives (or the simulators').

Which class a ``driver:`` name means, and how it is built from the station's
settings, is the driver's spec (``registry.py``); this module only opens the
station's instruments in order and closes what it opened when one fails.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, replace

from gyrocal.instruments.driver_spec import OpenRequest, Role
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.interfaces import Chamber, GyroStream, PowerSupply, RateTable
from gyrocal.instruments.registry import registry
from gyrocal.instruments.supply.coil import CoilDrive
from gyrocal.models.clock import Clock

RetryHook = Callable[[str, int, InstrumentError], None]


@dataclass
class Instruments:
    """The three instruments of a run, and the clock they live on."""

    chamber: Chamber
    table: RateTable
    gyro: GyroStream
    clock: Clock
    sample_rate_hz: float
    #: the supply powering the unit under test, when the station has one
    supply: PowerSupply | None = None
    #: the Helmholtz coil on two further channels of that supply (magnetic steps)
    coil: CoilDrive | None = None

    def close(self) -> None:
        for inst in (self.gyro, self.table, self.chamber, self.supply, self.coil):
            if inst is None:
                continue
            # Closing must never mask the run's real outcome.
            with contextlib.suppress(Exception):
                inst.close()


def open_role(role: Role, config, address: str, on_retry=None,
              sample_rate_hz: float | None = None, clock: Clock | None = None):
    """The driver a station section (``config``: its ChamberConfig, TableConfig, …) names, at
    ``address``, built by its registered spec with the section's settings."""
    spec = registry().get(role, config.driver)
    return spec.open(OpenRequest(address=address, timeout_s=config.timeout_s,
                                 retries=getattr(config, "retries", 0), settings=config.settings,
                                 on_retry=on_retry, sample_rate_hz=sample_rate_hz, clock=clock))


def open_chamber(config, address: str, on_retry=None) -> Chamber:
    """The chamber driver ``config`` (a station's ChamberConfig) names, at ``address``."""
    return _as(open_role(Role.CHAMBER, config, address, on_retry), Chamber, config.driver)


def open_table(config, address: str, on_retry=None) -> RateTable:
    """The rate-table driver of ``config`` (a station's TableConfig), at ``address``."""
    return _as(open_role(Role.TABLE, config, address, on_retry), RateTable, config.driver)


def open_gyro(config, port: str, sample_rate_hz: float | None = None,
              clock: Clock | None = None) -> GyroStream:
    """The gyro driver of ``config`` (a station's GyroConfig) on ``port``; ``clock``, the
    run's, decides how long its transport waits take (wall time without one)."""
    fs_hz = float(sample_rate_hz or config.sample_rate_hz)
    return _as(open_role(Role.GYRO, config, port, sample_rate_hz=fs_hz, clock=clock),
               GyroStream, config.driver)


def open_supply(config, address: str, on_retry=None) -> PowerSupply:
    """The supply of the unit under test ``config`` (a station's SupplyConfig) names."""
    return _as(open_role(Role.SUPPLY, config, address, on_retry), PowerSupply, config.driver)


def open_coil(supply_config, coil_config, address: str, on_retry=None) -> CoilDrive:
    """The coil's two channels: the station's supply driver at ``address``, one per polarity."""
    def channel(number: int) -> PowerSupply:
        config = replace(supply_config, settings={**supply_config.settings, "channel": number})
        return open_supply(config, address, on_retry)

    positive = channel(coil_config.positive_channel)
    try:
        negative = channel(coil_config.negative_channel)
    except BaseException:
        with contextlib.suppress(Exception):
            positive.close()
        raise
    return CoilDrive(positive, negative, coil_config.constant_t_per_a, coil_config.compliance_v,
                     coil_config.max_current_a)


def open_instruments(station, clock: Clock, addresses=None,
                     on_retry: RetryHook | None = None,
                     sample_rate_hz: float | None = None) -> Instruments:
    """Drivers for ``station``; ``addresses`` (a SimAddresses) replaces the file's addresses.

    ``sample_rate_hz`` is the gyro's configured output rate when it differs from
    the station file's (the simulated gyro runs at the procedure's rate).
    """

    def hook(role: str):
        if on_retry is None:
            return None
        return lambda attempt, exc: on_retry(role, attempt, exc)

    c, t, g = station.chamber, station.table, station.gyro
    fs_hz = float(sample_rate_hz or g.sample_rate_hz)
    s = station.supply
    opened: list = []
    try:
        opened.append(open_chamber(c, addresses.chamber if addresses else c.address,
                                   hook("chamber")))
        opened.append(open_table(t, addresses.table if addresses else t.address, hook("table")))
        opened.append(open_gyro(g, addresses.gyro if addresses else g.port, fs_hz, clock))
        if s is not None:
            opened.append(open_supply(s, addresses.supply if addresses else s.address,
                                      hook("supply")))
        if s is not None and station.coil is not None:
            opened.append(open_coil(s, station.coil, addresses.supply if addresses else s.address,
                                    hook("coil")))
    except BaseException:
        for inst in opened:
            with contextlib.suppress(Exception):
                inst.close()
        raise
    chamber, table, gyro = opened[:3]
    supply = opened[3] if s is not None else None
    coil = opened[4] if len(opened) > 4 else None
    return Instruments(chamber, table, gyro, clock, fs_hz, supply, coil)


def _as(instrument: object, interface: type, driver: str):
    """The driver's instance, checked to be what its role promises (a plug-in may not be)."""
    if not isinstance(instrument, interface):
        with contextlib.suppress(Exception):
            instrument.close()  # type: ignore[attr-defined]
        raise TypeError(f"driver {driver!r} built a {type(instrument).__name__}, which is not "
                        f"a {interface.__name__} (instruments/interfaces.py)")
    return instrument
