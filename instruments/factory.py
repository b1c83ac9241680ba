"""Build the drivers a station file names, at the addresses it gives (or the simulators').

This is the single place that maps a station's ``driver:`` names to driver
classes, so adding a chamber model means one line here and one module in
``instruments/chamber/``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

from gyrocal.instruments.chamber.watlow_f4 import WatlowF4
from gyrocal.instruments.chamber.watlow_f4t import WatlowF4T
from gyrocal.instruments.errors import InstrumentError
from gyrocal.instruments.gyro.stim300 import Stim300Gyro
from gyrocal.instruments.interfaces import Chamber, GyroStream, RateTable
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.table.acutrol import Acutrol3000Table
from gyrocal.models.clock import Clock

RetryHook = Callable[[str, int, InstrumentError], None]

#: Over ``socket://`` the RTU bytes cross TCP and no UART paces them; the baud rate
#: would only make pymodbus wait for imaginary character times (36 ms a read at 9600).
_SOCKET_BAUD = 921600


@dataclass
class Instruments:
    """The three instruments of a run, and the clock they live on."""

    chamber: Chamber
    table: RateTable
    gyro: GyroStream
    clock: Clock
    sample_rate_hz: float

    def close(self) -> None:
        for inst in (self.gyro, self.table, self.chamber):
            # Closing must never mask the run's real outcome.
            with contextlib.suppress(Exception):
                inst.close()


def open_chamber(config, address: str, on_retry=None) -> Chamber:
    """The chamber driver ``config`` (a station's ChamberConfig) names, at ``address``."""
    retry = RetryPolicy(attempts=config.retries)
    if config.driver == "watlow_f4":
        baud = _SOCKET_BAUD if address.startswith("socket://") else config.baudrate
        return WatlowF4(address, unit_id=config.unit_id, timeout_s=config.timeout_s,
                        retry=retry, baudrate=baud, parity=config.parity,
                        stop_bits=config.stop_bits, limit_input=config.limit_input,
                        on_retry=on_retry)
    if config.driver == "watlow_f4t":
        return WatlowF4T(address, unit_id=config.unit_id, timeout_s=config.timeout_s,
                         retry=retry, word_order=config.word_order, on_retry=on_retry)
    raise ValueError(f"unknown chamber driver {config.driver!r}")  # the loader refuses these


def open_table(config, address: str, on_retry=None) -> Acutrol3000Table:
    """The rate-table driver of ``config`` (a station's TableConfig), at ``address``."""
    return Acutrol3000Table(address, axis=config.axis, timeout_s=config.timeout_s,
                            retry=RetryPolicy(attempts=config.retries), on_retry=on_retry,
                            dialect=config.dialect)


def open_gyro(config, port: str, sample_rate_hz: float | None = None) -> Stim300Gyro:
    """The gyro driver of ``config`` (a station's GyroConfig) on ``port``."""
    fs_hz = float(sample_rate_hz or config.sample_rate_hz)
    return Stim300Gyro(port, baudrate=config.baudrate, sample_rate_hz=fs_hz,
                       with_temperature=config.with_temperature, lsb=config.rate_lsb,
                       timeout_s=config.timeout_s, axis=config.axis, crlf=config.crlf,
                       datagram=config.datagram,
                       accelerometer_range_g=config.accelerometer_range_g)


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
    opened: list = []
    try:
        chamber = open_chamber(c, addresses.chamber if addresses else c.address, hook("chamber"))
        opened.append(chamber)
        table = open_table(t, addresses.table if addresses else t.address, hook("table"))
        opened.append(table)
        gyro = open_gyro(g, addresses.gyro if addresses else g.port, sample_rate_hz)
        opened.append(gyro)
    except BaseException:
        for inst in opened:
            with contextlib.suppress(Exception):
                inst.close()
        raise
    return Instruments(chamber, table, gyro, clock, gyro.sample_rate_hz)
