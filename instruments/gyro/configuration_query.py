"""Asking a STIM300 for its configuration at connect, and judging the answer against the station.

A unit in normal mode answers ``C<CR>`` (upper case, no echo: TS1524 §8,
Table 8-1, p. 58) with one configuration datagram (§8.3, Table 8-5, p. 59)
that replaces the next normal-mode datagram — or more than one, when it is
the longer and the bit rate is low — while the stream goes on. The
datasheet gives no latency for the answer, so the wait is bounded by both
time and normal-mode datagrams (:data:`WAIT_FRAMES`).

What the answer is judged on (Table 5-16, pp. 31–33): the sample rate and
the datagram type with its CR LF, which the station declares; the gyro
output unit, which it cannot declare — gyrocal reads angular rate, so any
other unit (an incremental or integrated angle read as a rate) is a fault;
the unit-under-test axis, which must be active; the accelerometer range,
when the datagram carries acceleration. A unit that does not answer (a
replayed capture is one-way) is not a fault: the stream's own type, checked
as before, stands, and the report says the configuration is not confirmed.
"""

from __future__ import annotations

from dataclasses import dataclass

from gyrocal.instruments.gyro.configuration import (
    GyroOutputUnit,
    UnitConfiguration,
    output_unit_label,
)
from gyrocal.instruments.gyro.datagram_types import FrameLayout, datagram_type

#: the Normal Mode command (Table 8-5, p. 59): capital C, then the execution character CR
COMMAND = b"C\r"
#: normal-mode datagrams to wait for the answer after the command (not in the datasheet:
#: the answer replaces the *next* datagram; the rest covers a USB-serial adapter's latency)
WAIT_FRAMES = 100
#: the output unit gyrocal's decoding assumes (the rate LSB of §7.5.2.2.2 is °/s)
EXPECTED_OUTPUT = GyroOutputUnit.ANGULAR_RATE
NOT_CONFIRMED = "configuration not confirmed: no answer to C (TS1524 §8.3)"


@dataclass(frozen=True)
class ConfigurationAnswer:
    """What the unit said when asked (``configuration`` None: it did not answer)."""

    configuration: UnitConfiguration | None
    replaced_frames: int | None = None   # normal-mode datagrams the answer took the place of
    contradictions: tuple[str, ...] = ()  # how it contradicts the station (see :func:`mismatches`)

    @property
    def confirmed(self) -> bool:
        """The unit answered and its answer agrees with the station."""
        return self.configuration is not None and not self.contradictions

    def describe(self) -> str:
        if self.configuration is None:
            return NOT_CONFIRMED
        replaced = ("" if self.replaced_frames is None
                    else f"; it replaced {self.replaced_frames} normal-mode datagram(s)")
        verdict = "confirmed" if self.confirmed else "contradicts the station"
        return f"configuration {verdict} (C, TS1524 §8.3): {self.configuration.describe()}{replaced}"

    def record(self) -> dict[str, object]:
        """The journal's fields (JSON): what the unit said, field by field."""
        config = self.configuration
        if config is None:
            return {"confirmed": False, "answered": False, "description": self.describe()}
        return {
            "confirmed": self.confirmed, "answered": True, "description": self.describe(),
            "contradictions": list(self.contradictions), "revision": config.revision,
            "firmware": config.firmware, "sample_rate_hz": config.sample_rate_hz,
            "datagram": f"0x{config.datagram:02X}", "crlf": config.crlf, "bit_rate": config.bit_rate,
            "gyro_output_unit": output_unit_label(config.gyro_output_code),
            "gyro_axes_active": list(config.gyro_axes_active),
            "gyro_filter_hz": list(config.gyro_filter_hz),
            "gyro_range_dps": list(config.gyro_range_dps),
            "accelerometer_range_g": list(config.accelerometer_range_g),
            "replaced_frames": self.replaced_frames,
        }


@dataclass(frozen=True)
class Declared:
    """What the station declares of the unit, as the driver holds it."""

    sample_rate_hz: float
    layout: FrameLayout
    axis: int                       # 0, 1, 2: the unit-under-test axis
    accelerometer_range_g: int


def mismatches(config: UnitConfiguration, declared: Declared) -> list[str]:
    """Each way the unit's configuration contradicts the station, naming both and the table."""
    found: list[str] = []
    if config.sample_rate_hz != declared.sample_rate_hz:
        unit = "external trigger" if config.sample_rate_hz is None else f"{config.sample_rate_hz:g} samples/s"
        found.append(f"the unit is configured for {unit} (TS1524 Table 5-16 byte 3); the station "
                     f"declares {declared.sample_rate_hz:g} Hz")
    layout = declared.layout
    if (config.datagram, config.crlf) != (layout.identifier, layout.crlf):
        found.append(f"the unit is configured for datagram {datagram_type(config.datagram).label()}"
                     f"{' with CR LF' if config.crlf else ''} (TS1524 Table 5-16 byte 3, Table 5-21); "
                     f"the station declares {layout.kind.label()}{' with CR LF' if layout.crlf else ''}")
    if config.gyro_output_unit is not EXPECTED_OUTPUT:
        found.append(f"the unit's gyro output unit is {output_unit_label(config.gyro_output_code)} "
                     f"(TS1524 Table 5-16 byte 5); gyrocal reads {EXPECTED_OUTPUT.label()}: "
                     "reconfigure the unit (its service mode)")
    if not config.gyro_axes_active[declared.axis]:
        axis = "xyz"[declared.axis]
        found.append(f"the unit's gyro {axis} axis is inactive (TS1524 Table 5-16 byte 5); the station "
                     f"declares the unit under test on the {axis} axis")
    if layout.kind.acceleration:
        wrong = [g for g in config.accelerometer_range_g if g != declared.accelerometer_range_g]
        if wrong:
            ranges = "/".join("?" if g is None else f"{g}" for g in config.accelerometer_range_g)
            found.append(f"the unit's accelerometer range is ±{ranges} g on x/y/z (TS1524 Table 5-16 "
                         f"bytes 17–18); the station declares ±{declared.accelerometer_range_g} g")
    return found
