"""How a run drove its instruments: the manifest's and ``run_started`` identity's ``mode``."""

from __future__ import annotations

from enum import Enum


class RunMode(str, Enum):
    SIM = "sim"            # simulated instruments on loopback (a dry run: no unit calibrated)
    STATION = "station"    # the station's real instruments
