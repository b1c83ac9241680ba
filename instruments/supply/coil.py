"""A Helmholtz coil on two channels of a programmable supply: a field set, read back, switched off.

A supply channel is unipolar, so the coil's two polarities are two channels
wired in opposition (each through its own winding or a diode pair): the
positive channel gives +B along the coil's axis, the negative one -B. Each
runs in constant current — its voltage (the compliance) set above what the
coil needs, its current limit set to the current wanted — so the field is the
coil constant × the measured current, read back on both channels.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.instruments.interfaces import PowerSupply

#: the measured field must be within this fraction of the set one (plus FIELD_FLOOR of
#: the coil's reach): a channel that is not in constant current reads far below it
FIELD_TOLERANCE = 0.01
FIELD_FLOOR = 1e-3


@dataclass(frozen=True)
class CoilReading:
    """Both channels read back, and the field they make (T, along the coil's axis)."""

    positive_current_a: float
    negative_current_a: float
    positive_on: bool
    negative_on: bool
    field_t: float


class CoilDrive:
    """Sets the coil's field through two supply channels; never leaves both on."""

    def __init__(self, positive: PowerSupply, negative: PowerSupply, constant_t_per_a: float,
                 compliance_v: float, max_current_a: float) -> None:
        self.positive, self.negative = positive, negative
        self.constant_t_per_a = float(constant_t_per_a)
        self.compliance_v, self.max_current_a = float(compliance_v), float(max_current_a)

    @property
    def max_field_t(self) -> float:
        return self.constant_t_per_a * self.max_current_a

    def current_for_a(self, field_t: float) -> float:
        """|I| for the field (the station's coil constant); above the coil's maximum is refused."""
        current = abs(field_t) / self.constant_t_per_a
        if current > self.max_current_a * (1.0 + 1e-12):
            raise ValueError(f"coil: {field_t:g} T needs {current:g} A, above its "
                             f"{self.max_current_a:g} A")
        return current

    def set_field(self, field_t: float) -> CoilReading:
        """The idle polarity off first, then the working one at |B|/k; 0 T switches both off."""
        current = self.current_for_a(field_t)
        working, idle = (self.positive, self.negative) if field_t > 0 else (self.negative, self.positive)
        idle.set_output(False)
        if current == 0.0:
            working.set_output(False)
        else:
            working.configure(self.compliance_v, current)
            working.set_output(True)
        return self.read()

    def read(self) -> CoilReading:
        pos, neg = self.positive.read(), self.negative.read()
        i_pos = pos.current_a if pos.output_on else 0.0
        i_neg = neg.current_a if neg.output_on else 0.0
        return CoilReading(pos.current_a, neg.current_a, pos.output_on, neg.output_on,
                           self.constant_t_per_a * (i_pos - i_neg))

    def mismatch(self, reading: CoilReading, field_t: float) -> str | None:
        """Why ``reading`` is not the field that was set, or None when it is."""
        if reading.positive_on and reading.negative_on:
            return "both coil channels are on (the polarities would cancel)"
        allowed = FIELD_TOLERANCE * abs(field_t) + FIELD_FLOOR * self.max_field_t
        if abs(reading.field_t - field_t) > allowed:
            return (f"the coil reads {reading.field_t:.6g} T, set {field_t:.6g} T (a channel not "
                    "in constant current: compliance voltage too low, or the coil open)")
        return None

    def off(self) -> CoilReading:
        for channel in (self.positive, self.negative):
            channel.set_output(False)
        return self.read()

    def reset_link(self) -> None:
        for channel in (self.positive, self.negative):
            channel.reset_link()

    def close(self) -> None:
        for channel in (self.positive, self.negative):
            channel.close()
