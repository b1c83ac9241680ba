"""The gyro part of ``gyrocal station check``: listen to the unit, judge what a run relies on.

Only listens (the STIM300 takes no commands in normal mode). Reports the
datagram the driver decodes, the sample rate read from the datagram counter
(TS1524 §7.5.2.2.18: the counter counts the unit's internal 2000 Hz samples,
so it steps by 2000 / fs per datagram), the status bits seen and the mean of
each axis over the listening window.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gyrocal.instruments.interfaces import GyroStream

#: The unit's internal sample rate the counter counts (TS1524 §7.5.2.2.18).
INTERNAL_RATE_HZ = 2000.0
#: How long to listen, seconds of samples at the configured rate.
LISTEN_S = 1.0


def counter_rate_hz(counter: np.ndarray) -> float | None:
    """fs = 2000 / (the counter's usual step per datagram), or None with fewer than 2 frames."""
    if len(counter) < 2:
        return None
    steps = np.diff(np.asarray(counter, dtype=np.int64)) % 256
    steps = steps[steps > 0]
    if not len(steps):
        return None
    return INTERNAL_RATE_HZ / float(np.median(steps))


def check_gyro_stream(gyro: GyroStream, sample_rate_hz: float) -> tuple[dict[str, Any], list[str]]:
    """(facts, problems) of ``LISTEN_S`` of the stream at the station's ``sample_rate_hz``."""
    facts: dict[str, Any] = {"identity": gyro.identify().description}
    problems: list[str] = []
    n = max(10, int(round(sample_rate_hz * LISTEN_S)))
    gyro.flush()
    block = gyro.read_samples(n, timeout_s=LISTEN_S + 2.0)
    facts["frames_valid"] = len(block)
    facts["crc_errors"] = block.crc_errors
    facts["lost_frames"] = block.lost_frames
    facts["garbage_bytes"] = block.garbage_bytes
    rate_hz = counter_rate_hz(block.counter)
    facts["sample_rate_hz_by_counter"] = rate_hz
    if rate_hz is None:
        problems.append("too few frames to read the sample rate from the counter")
    elif abs(rate_hz - sample_rate_hz) > 1e-6 * sample_rate_hz:
        problems.append(f"the counter says {rate_hz:g} Hz (2000 Hz / its step); the station "
                        f"declares {sample_rate_hz:g} Hz")
    status = np.asarray(block.status, dtype=np.uint8)
    seen = int(np.bitwise_or.reduce(status)) if len(status) else 0
    facts["status_bits_seen"] = f"0x{seen:02X}"
    facts["status_flagged"] = int(np.count_nonzero(status))
    if seen:
        problems.append(f"status byte nonzero in {facts['status_flagged']} of {len(status)} "
                        f"datagrams (bits 0x{seen:02X})")
    xyz = block.rate_xyz if block.rate_xyz is not None else np.asarray(block.rate)[:, None]
    facts["gyro_mean"] = [round(float(v), 6) for v in np.mean(xyz, axis=0)] if len(block) else []
    if block.crc_errors or block.lost_frames:
        problems.append(f"{block.crc_errors} CRC error(s), {block.lost_frames} lost frame(s) "
                        f"in {len(block)} datagrams")
    return facts, problems
