"""What an instrument says it is: the serial in its identity reply.

One reader for the report's declared-vs-reported identity check and the
station's serial locks (``gyrocal.record.locks``), which sit on different
layers; the parsing belongs with the instruments that produce the text.
"""

from __future__ import annotations

import re


def reported_serial(description: str | None) -> str | None:
    """The serial an instrument reported: ``*IDN?`` field 3, or ``serial X`` in the text.

    One reader for the report's identity check and the station's serial locks.
    """
    if not description:
        return None
    fields = [f.strip() for f in description.split(",")]
    if len(fields) == 4 and " " not in fields[2]:
        return fields[2] or None                 # IEEE 488.2 *IDN?: maker,model,serial,firmware
    match = re.search(r"\bserial\s+([^\s,;]+)", description)   # ends at a space, comma or semicolon
    return match.group(1) if match else None



def serial_change(recorded_serial: str | None, description: str | None) -> str | None:
    """The serial an identity reply reports when it is not ``recorded_serial`` (else None).

    A run resumed on another unit would put two units' samples under one
    certificate (a swapped gyro), or measure later steps with an instrument
    whose calibration the run's traceability does not list. Only two serials
    that both exist and differ are a change: an instrument that does not say
    its serial (a STIM300 that does not answer ``I<CR>``, a replayed capture)
    cannot be told apart, and is left to the report's declared-vs-reported
    check. Serials compare without case or surrounding blanks (as the locks key them).
    """
    now = reported_serial(description)
    if recorded_serial is None or now is None \
            or recorded_serial.strip().upper() == now.strip().upper():
        return None
    return now
