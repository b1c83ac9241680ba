"""Libraries' own loggers, quieted: the journal and the collapsed retry console say it once."""

from __future__ import annotations

import logging


def quiet_library_logs(debug: bool = False) -> None:
    """pymodbus logs every retry to stderr; the journal is where retries belong."""
    level = logging.DEBUG if debug else logging.CRITICAL
    # the drivers' own retry warnings too: retries reach the console once, collapsed
    # (retry_console.py), and the journal in full
    for name in ("pymodbus", "pyvisa", "pyvisa_py", "gyrocal.instruments"):
        logging.getLogger(name).setLevel(level)
