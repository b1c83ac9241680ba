"""The special datagrams of a decoded capture: where they were, what they said, what they replaced.

A unit sends its part number, serial number, configuration (and bias trim
offset, if configured) at start-up before normal mode (TS1524 §7.5.1, p. 47),
and one of them in place of normal-mode datagrams when asked ``N``, ``I`` or
``C`` (§8.1–8.4, pp. 58–59). ``gyrocal decode`` cuts them out with the
driver's search (instruments/gyro/special_datagrams.py), so they are neither
garbage nor, across an answer, lost frames: the counter gap across one is the
datagrams it replaced (the shared :func:`replaced_frames` rule).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.instruments.gyro.configuration import UnitConfiguration
from gyrocal.instruments.gyro.special_datagrams import (
    BiasTrimOffset,
    Found,
    PartNumber,
    SerialNumber,
    SpecialValue,
    replaced_frames,
)


@dataclass(frozen=True)
class SpecialInCapture:
    """One special datagram found in the capture."""

    found: Found                    # byte offsets in the capture, kind and decoded value
    identifier: int
    after_frames: int               # normal-mode datagrams decoded before it
    replaced_frames: int | None     # counter gap across it; None without a datagram on each side


def place_specials(found: list[Found], identifiers: list[int], frames_before: list[int],
                   counter: np.ndarray, counter_step: int) -> list[SpecialInCapture]:
    """Each special with the normal-mode datagrams around it.

    Specials back to back (the start-up sequence, or answers with no datagram
    between) share one counter gap; it is given to the first of them, 0 to the others.
    """
    out: list[SpecialInCapture] = []
    for index, (hit, identifier, before) in enumerate(zip(found, identifiers, frames_before, strict=True)):
        replaced = None
        if 0 < before < counter.size:
            shared = index > 0 and frames_before[index - 1] == before
            replaced = 0 if shared else replaced_frames(int(counter[before - 1]), int(counter[before]),
                                                        counter_step)
        out.append(SpecialInCapture(hit, identifier, before, replaced))
    return out


def configuration_fields(config: UnitConfiguration) -> dict:
    """Table 5-16's fields that decode reports (the ``unit_configuration`` key)."""
    return {"datagram_id": f"0x{config.datagram:02X}", "sample_rate_hz": config.sample_rate_hz,
            "crlf": config.crlf, "bit_rate": config.bit_rate,
            "accelerometer_range_g": list(config.accelerometer_range_g),
            "firmware": config.firmware, "revision": config.revision}


def _value_fields(value: SpecialValue) -> dict:
    if isinstance(value, PartNumber):
        return {"part_number": value.part_number, "revision": value.revision}
    if isinstance(value, SerialNumber):
        return {"serial_number": value.serial}
    if isinstance(value, BiasTrimOffset):
        return {"gyro_dps": list(value.gyro_dps), "accelerometer_counts": list(value.accelerometer_counts),
                "inclinometer_counts": list(value.inclinometer_counts), "reference": value.reference,
                "saves_left": value.saves_left}
    return configuration_fields(value)


def special_figures(specials: list[SpecialInCapture]) -> dict:
    """``special_datagrams`` (each, in capture order) and the unit's identity from the first of each kind."""
    listed = [{"kind": s.found.kind.name, "datagram_id": f"0x{s.identifier:02X}",
               "byte_offset": s.found.start, "bytes": s.found.end - s.found.start,
               "after_frames": s.after_frames, "replaced_frames": s.replaced_frames,
               "value": _value_fields(s.found.value)} for s in specials]
    out: dict = {"special_datagrams": listed,
                 "replaced_frames": sum(s.replaced_frames or 0 for s in specials)}
    for s in specials:
        value = s.found.value
        if isinstance(value, PartNumber) and "part_number" not in out:
            out.update(part_number=value.part_number, part_number_revision=value.revision)
        elif isinstance(value, SerialNumber) and "serial_number" not in out:
            out["serial_number"] = value.serial
        elif isinstance(value, BiasTrimOffset) and "bias_trim_offset" not in out:
            out["bias_trim_offset"] = _value_fields(value)
    return out


def describe_special(special: SpecialInCapture) -> str:
    """One printed line: where it was and what it said."""
    replaced = ("" if special.replaced_frames is None
                else f", replaced {special.replaced_frames} datagram(s)")
    return (f"byte {special.found.start} (after {special.after_frames} datagrams{replaced}): "
            f"{special.found.value.describe()}")
