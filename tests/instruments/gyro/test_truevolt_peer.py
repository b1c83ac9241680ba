"""Someone else's driver for a real Keysight DMM drives our simulated 34465A.

PyMeasure's Agilent34410A (the Truevolt's predecessor; ``MEAS:VOLT:DC? DEF,DEF``)
reads the simulated meter over a raw socket, so the simulator is not only ever
checked against our own driver. QCoDeS's Keysight 34465A driver, written for
the Truevolt itself, reads it too (test_truevolt_qcodes_peer.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from pymeasure.adapters import VISAAdapter
from pymeasure.instruments.agilent import Agilent34410A

from gyrocal.instruments.sim.faults import FaultInjector
from gyrocal.instruments.sim.truevolt_server import FAULTS, SimulatedTruevolt
from gyrocal.models.clock import SimClock


def test_pymeasure_34410a_reads_the_simulated_meters_dc_volts():
    clock = SimClock()
    clock.advance_to(10.0)

    def source(t_s):
        t = np.asarray(t_s, dtype=float)
        return 0.5 + 0.01 * t, np.full(t.shape, np.nan)     # 0.6 V at t = 10 s

    with SimulatedTruevolt(source, clock, FaultInjector(FAULTS)) as sim:
        adapter = VISAAdapter(sim.address, visa_library="@py", read_termination="\n",
                              write_termination="\n", timeout=2000)
        peer = Agilent34410A(adapter)
        assert peer.voltage_dc == pytest.approx(0.6, abs=1e-9)
        assert "34465A" in peer.id
        assert "MEAS:VOLT:DC? DEF,DEF" in sim.received
        adapter.close()
