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
