"""Keysight E36300-series supply (E36311A/E36312A/E36313A) powering the unit under test, SCPI over LAN.

Commands, with their channel list ``(@n)``: ``VOLT v, (@n)`` and ``CURR a, (@n)``
(level and current limit), ``OUTP 1|0, (@n)``, ``OUTP? (@n)``, ``MEAS:VOLT? (@n)``,
``MEAS:CURR? (@n)``, ``VOLT? (@n)``, ``CURR? (@n)``; errors from ``SYST:ERR?``.
The E36300 programming guide was not available; the spellings are those of
PyMeasure's KeysightE36312A driver (pymeasure/instruments/keysight/keysightE36312A.py)
and are marked *unconfirmed* in docs/protocol-elements.md.

A configure is read back (``VOLT?``/``CURR?``) so a setting the supply clipped to
its range is caught before the unit is powered.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from gyrocal.instruments.errors import InstrumentError, InstrumentSafetyError
from gyrocal.instruments.interfaces import Identity, SupplyReading
from gyrocal.instruments.retry import RetryPolicy
from gyrocal.instruments.scpi_link import ScpiLink

DRIVER_NAME = "keysight_e36300"
#: a set level must read back within this fraction (plus 1 mV / 1 mA) of what was set
READBACK_TOLERANCE = 1e-3


def level(command: str, value: float, channel: int) -> str:
    """``VOLT 5, (@1)``: a level with its channel list."""
    return f"{command} {value:g}, (@{channel})"


class KeysightE36300Supply:
    """One output channel of an E36300 supply."""

    def __init__(self, resource: str, channel: int = 1, timeout_s: float = 1.0,
                 retry: RetryPolicy | None = None, name: str = "supply",
                 on_retry: Callable[[int, InstrumentError], None] | None = None) -> None:
        if channel not in (1, 2, 3):
            raise ValueError(f"{name}: channel must be 1, 2 or 3, got {channel!r}")
        self.resource, self.channel, self.name = resource, channel, name
        self.link = ScpiLink(resource, name, timeout_s, retry or RetryPolicy(), on_retry)

    @property
    def _ch(self) -> str:
        return f"(@{self.channel})"

    def identify(self) -> Identity:
        return Identity("supply", DRIVER_NAME, self.resource, self.link.ask("*IDN?"))

    def configure(self, voltage_v: float, current_limit_a: float) -> None:
        for command, value, unit in (("VOLT", voltage_v, "V"), ("CURR", current_limit_a, "A")):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{self.name}: {command} must be a finite number >= 0, got {value!r}")
            self.link.send(level(command, value, self.channel))
            read = self.link.ask_float(f"{command}? {self._ch}")
            if abs(read - value) > READBACK_TOLERANCE * abs(value) + 1e-3:
                raise InstrumentSafetyError(self.name, f"{command}? {self._ch}",
                                            f"set {value:g} {unit}, reads back {read:g} {unit}",
                                            reply=str(read))

    def set_output(self, on: bool) -> None:
        self.link.send(f"OUTP {1 if on else 0}, {self._ch}")

    def read(self) -> SupplyReading:
        state = self.link.ask(f"OUTP? {self._ch}").strip()
        if state not in ("0", "1"):
            raise InstrumentError(self.name, f"OUTP? {self._ch}", "expected 0 or 1", reply=state,
                                  transient=True)
        return SupplyReading(voltage_v=self.link.ask_float(f"MEAS:VOLT? {self._ch}"),
                             current_a=self.link.ask_float(f"MEAS:CURR? {self._ch}"),
                             output_on=state == "1")

    def reset_link(self) -> None:
        self.link.reset()

    def close(self) -> None:
        self.link.close()
