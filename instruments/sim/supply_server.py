"""Simulated Keysight E36300 supply powering a simulated unit under test (a resistive load).

The unit draws V/R; when that exceeds the current limit the supply goes into
constant current (current = limit, voltage = limit·R), as a real supply does.
The command set is the one the driver documents (``keysight_e36300.py``):
levels and queries with a ``(@n)`` channel list; a missing channel list means
the selected channel 1, as the peer PyMeasure driver never omits it.

Faults (``--inject supply.NAME``): ``overcurrent`` (the unit draws ``factor``
times its normal current, default 3: persistent while armed), ``dropout`` (the
output switches itself off, persistent), ``no_reply``, ``drop_connection``.
"""

from __future__ import annotations

import re

import numpy as np

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.scpi_server import COMMON_FAULTS, ScpiError, SimulatedScpiInstrument

FAULTS = (*COMMON_FAULTS, "overcurrent", "dropout")
IDN = "Keysight Technologies,E36312A,MY00000001,1.0.4-1.0.0-1.12"
#: E36312A channel ratings (V, A): channel 1 6 V/5 A, channels 2 and 3 25 V/1 A (data sheet)
RATINGS = {1: (6.18, 5.15), 2: (25.75, 1.03), 3: (25.75, 1.03)}

_CHANNEL = re.compile(r"\(@(\d)\)\s*$")


class SimulatedE36300(SimulatedScpiInstrument):
    #: what a resumed dry run restores (models/sim_state.py): levels, outputs, when each was
    #: switched on (a powered unit's warm-up runs from it), the load current's noise stream
    SIM_STATE = ("voltage_v", "current_a", "output", "_on_since_s", "_rng")

    def __init__(self, faults: FaultInjector | None = None, load_ohm: float = 20.0,
                 noise_a: float = 2e-4, seed: int = 0, clock=None) -> None:
        super().__init__(faults or FaultInjector(FAULTS, owner="simulated supply"), IDN)
        self.load_ohm, self.noise_a = float(load_ohm), float(noise_a)
        self.voltage_v = {ch: 0.0 for ch in RATINGS}
        self.current_a = {ch: 0.1 for ch in RATINGS}
        self.output = {ch: False for ch in RATINGS}
        #: the station clock; with it the supply notes when each output was switched on
        self.clock = clock
        self._on_since_s: dict[int, float | None] = {ch: None for ch in RATINGS}
        self._rng = np.random.default_rng(seed)

    def reseed(self, seed) -> None:
        """The load current's noise draws from ``seed`` from here (reproducible attempts)."""
        self._rng = np.random.default_rng(seed)

    def state(self, channel: int) -> tuple[float, float]:
        """(volts, amps) at the output terminals now."""
        if self.faults.is_armed("dropout"):
            self.output[channel] = False
        if not self.output[channel]:
            return 0.0, 0.0
        params = self.faults.params("overcurrent")
        ohm = self.load_ohm / float(params.get("factor", 3.0)) if params is not None else self.load_ohm
        volts, limit = self.voltage_v[channel], self.current_a[channel]
        if volts / ohm > limit:                       # constant current
            return limit * ohm, limit
        amps = volts / ohm + float(self._rng.normal(0.0, self.noise_a))
        return volts, max(0.0, amps)

    def output_current_a(self, channel: int) -> float:
        """The current the channel drives now, without the meter's noise (what a coil on it
        turns into field): constant current at the limit, else V/R, 0 when off."""
        if not self.output[channel] or self.faults.is_armed("dropout"):
            return 0.0
        return min(self.voltage_v[channel] / self.load_ohm, self.current_a[channel])

    def on_since_s(self, channel: int) -> float | None:
        """Clock time the channel's output was last switched on; None while it is off (a
        powered unit on it restarts then: instruments/sim/station_sim.py)."""
        if not self.output[channel] or self.faults.is_armed("dropout"):
            return None
        return self._on_since_s[channel]

    def answer(self, line: str) -> str | None:
        match = _CHANNEL.search(line)
        channel = int(match.group(1)) if match else 1
        if channel not in RATINGS:
            raise ScpiError(-222, "Data out of range")
        body = _CHANNEL.sub("", line).strip().rstrip(",").strip()
        head, _, arg = body.partition(" ")
        head = head.upper()
        if head in ("MEAS:VOLT?", "MEASURE:VOLTAGE?", "MEAS:VOLT:DC?"):
            return f"{self.state(channel)[0]:+.6E}"
        if head in ("MEAS:CURR?", "MEAS:CURRENT?", "MEASURE:CURRENT?", "MEAS:CURR:DC?"):
            return f"{self.state(channel)[1]:+.6E}"
        if head in ("VOLT?", "VOLTAGE?"):
            return f"{self.voltage_v[channel]:+.6E}"
        if head in ("CURR?", "CURRENT?"):
            return f"{self.current_a[channel]:+.6E}"
        if head in ("OUTP?", "OUTPUT?"):
            self.state(channel)
            return "1" if self.output[channel] else "0"
        if head in ("VOLT", "VOLTAGE", "CURR", "CURRENT", "OUTP", "OUTPUT"):
            self._set(head, arg.strip(), channel)
            return None
        raise ScpiError(-113, "Undefined header")

    def _set(self, head: str, arg: str, channel: int) -> None:
        if head.startswith("OUTP"):
            if arg.upper() not in ("1", "0", "ON", "OFF"):
                raise ScpiError(-224, "Illegal parameter value")
            was_on = self.output[channel]
            self.output[channel] = arg.upper() in ("1", "ON") and not self.faults.is_armed("dropout")
            if self.output[channel] and not was_on:
                self._on_since_s[channel] = self.clock.now_s() if self.clock is not None else 0.0
            return
        try:
            value = float(arg)
        except ValueError:
            raise ScpiError(-104, "Data type error") from None
        max_v, max_a = RATINGS[channel]
        limit = max_v if head.startswith("VOLT") else max_a
        if not 0.0 <= value <= limit:
            raise ScpiError(-222, "Data out of range")
        (self.voltage_v if head.startswith("VOLT") else self.current_a)[channel] = value
