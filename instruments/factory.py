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
    chamber_addr = addresses.chamber if addresses else c.address
    table_addr = addresses.table if addresses else t.address
    gyro_port = addresses.gyro if addresses else g.port
    opened: list = []
    try:
        chamber_retry = RetryPolicy(attempts=c.retries)
        if c.driver == "watlow_f4":
            baud = _SOCKET_BAUD if chamber_addr.startswith("socket://") else c.baudrate
            chamber = WatlowF4(chamber_addr, unit_id=c.unit_id, timeout_s=c.timeout_s,
                               retry=chamber_retry, baudrate=baud, parity=c.parity,
                               stop_bits=c.stop_bits, limit_input=c.limit_input,
                               on_retry=hook("chamber"))
        elif c.driver == "watlow_f4t":
            chamber = WatlowF4T(chamber_addr, unit_id=c.unit_id, timeout_s=c.timeout_s,
                                retry=chamber_retry, word_order=c.word_order,
                                on_retry=hook("chamber"))
        else:  # the station loader already refuses unknown drivers
            raise ValueError(f"unknown chamber driver {c.driver!r}")
        opened.append(chamber)
        table = Acutrol3000Table(table_addr, axis=t.axis, timeout_s=t.timeout_s,
                                 retry=RetryPolicy(attempts=t.retries), on_retry=hook("table"),
                                 dialect=t.dialect)
        opened.append(table)
        fs_hz = float(sample_rate_hz or g.sample_rate_hz)
        gyro = Stim300Gyro(gyro_port, baudrate=g.baudrate, sample_rate_hz=fs_hz,
                           with_temperature=g.with_temperature, lsb=g.rate_lsb,
                           timeout_s=g.timeout_s, axis=g.axis, crlf=g.crlf, datagram=g.datagram,
                           accelerometer_range_g=g.accelerometer_range_g)
        opened.append(gyro)
    except BaseException:
        for inst in opened:
            with contextlib.suppress(Exception):
                inst.close()
        raise
    return Instruments(chamber, table, gyro, clock, fs_hz)
