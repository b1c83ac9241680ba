"""Simulated Keysight 53230A counting a pulse gyro: a SCPI server whose totals come from the gyro model.

Between ``INIT`` and ``ABORt`` back-to-back gates of ``g`` seconds run; gate k
counts the whole pulses the model's angle crossed in it (the phase carried from
gate to gate, models/pulse_counting.py), so the count is the floor or ceiling of
the true advance exactly as on a real ring-laser gyro. On simulated time an
empty memory lets one block of gates run when asked (the clock advances).

Faults: ``stall`` (the gates stop), ``no_reply``, ``drop_connection``.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Callable

import numpy as np

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.scpi_server import COMMON_FAULTS, ScpiError, SimulatedScpiInstrument
from gyrocal.models.clock import Clock, SimClock
from gyrocal.models.pulse_counting import count_pulses

FAULTS = (*COMMON_FAULTS, "stall")
IDN = "Keysight Technologies,53230A,MY00000003,03.05-1519.666-1.19-4.15-127-155-35"
_BLOCK = 256
_TOTALIZE = re.compile(r"^CONF(?:IGURE)?:TOT(?:ALIZE)?:TIM(?:ED)?\s+([0-9.eE+-]+)\s*,\s*\(@(\d)\)$",
                       re.IGNORECASE)


class SimulatedCounter(SimulatedScpiInstrument):
    #: what a resumed dry run restores (models/sim_state.py): the gate, the reading memory,
    #: the next gate and the pulse phase carried between gates
    SIM_STATE = ("gate_s", "sample_count", "_memory", "_k_next", "_phase", "_t_init")

    def __init__(self, source: Callable, clock: Clock, pulse_weight_arcsec: float,
                 faults: FaultInjector | None = None) -> None:
        super().__init__(faults or FaultInjector(FAULTS, owner="simulated counter"), IDN)
        self.source, self.clock = source, clock
        self.pulse_deg = float(pulse_weight_arcsec) / 3600.0
        self.gate_s = 0.1
        self.sample_count = 1
        self._memory: deque[float] = deque()
        self._k_next = 0
        self._phase = 0.0
        self._t_init: float | None = None

    def answer(self, line: str) -> str | None:
        head, _, arg = line.partition(" ")
        key = head.upper()
        match = _TOTALIZE.match(line)
        if match:
            self.gate_s = float(match.group(1))
            return None
        if key in ("INIT", "INITIATE"):
            self._memory.clear()
            self._k_next, self._phase = 0, 0.0
            self._t_init = math.ceil(self.clock.now_s() / self.gate_s) * self.gate_s
            return None
        if key in ("ABOR", "ABORT"):
            self._t_init = None
            return None
        if key in ("SAMP:COUN", "SAMPLE:COUNT"):
            self.sample_count = int(float(arg))
            return None
        if key in ("TRIG:SOUR", "TRIGGER:SOURCE", "TRIG:COUN", "TRIGGER:COUNT"):
            return None
        if key in ("DATA:POIN?", "DATA:POINTS?"):
            self._run_gates()
            return str(len(self._memory))
        if key in ("DATA:REM?", "DATA:REMOVE?"):
            count = int(arg.split(",")[0])
            if count > len(self._memory):
                raise ScpiError(-222, "Data out of range")
            return ",".join(f"{self._memory.popleft():+.0f}" for _ in range(count))
        raise ScpiError(-113, "Undefined header")

    def _run_gates(self) -> None:
        if self._t_init is None or self.faults.is_armed("stall"):
            return
        if isinstance(self.clock, SimClock):
            if self._memory:
                return
            k_end = self._k_next + _BLOCK
            self.clock.advance_to(self._t_init + k_end * self.gate_s)
        else:
            k_end = math.floor((self.clock.now_s() - self._t_init) / self.gate_s)
        k_end = min(k_end, self.sample_count)
        if k_end <= self._k_next:
            return
        k = np.arange(self._k_next, k_end)
        # the model's rate at each gate (on the model's sample grid), times the gate: the
        # angle advance in the gate
        rate_dps, _ = self.source(self._t_init + k * self.gate_s)
        rate_dps = np.asarray(rate_dps, dtype=np.float64).reshape(len(k), -1)[:, 0]
        counts, self._phase = count_pulses(rate_dps * self.gate_s / self.pulse_deg, self._phase)
        self._memory.extend(counts.tolist())
        self._k_next = k_end
