"""The gyro part of ``gyrocal station check``: listen to the unit, judge what a run relies on.

First asks the unit for its configuration (``C<CR>``, TS1524 §8.3), then its
part and serial numbers (``N<CR>``, ``I<CR>``, §8.1–8.2; none of the three
commands changes anything): a configuration that contradicts the
station (rate, datagram, gyro output unit, the axis, accelerometer range;
Table 5-16) is the driver's fault naming both; no answer (a one-way replay)
is reported as "configuration not confirmed", not as a problem. The driver's
``detect`` reads the datagram type and the counter step from the stream and
compares them with the station's declaration (TS1524 Table 5-21; §7.5.2.2.18:
the counter counts the unit's internal 2000 Hz samples, so fs = 2000 / step);
a mismatch is the driver's fault naming both, reported as the gyro's problem.
Then one second of samples gives the status bits seen and the mean of each
axis of every sensor the datagram carries.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gyrocal.instruments.gyro.stim300 import Stim300Gyro

#: How long to listen, seconds of samples at the configured rate.
LISTEN_S = 1.0


def _means(values: np.ndarray | None) -> list[float] | None:
    if values is None or not len(values):
        return None
    return [round(float(v), 6) for v in np.mean(np.asarray(values, dtype=np.float64), axis=0)]


def _bits(status: np.ndarray | None) -> tuple[int, int]:
    """(OR of every status byte, how many are nonzero)."""
    if status is None or not len(status):
        return 0, 0
    status = np.asarray(status, dtype=np.uint8)
    return int(np.bitwise_or.reduce(status)), int(np.count_nonzero(status))


def check_gyro_stream(gyro: Stim300Gyro, sample_rate_hz: float) -> tuple[dict[str, Any], list[str]]:
    """(facts, problems) of the stream, as the station declares it at ``sample_rate_hz``."""
    problems: list[str] = []
    answer = gyro.confirm_configuration(timeout_s=LISTEN_S)   # flushes; faults on a contradiction
    unit = gyro.ask_identity(timeout_s=LISTEN_S)             # N, I: who the unit says it is
    facts: dict[str, Any] = {"identity": gyro.identify().description, "unit": unit.describe()}
    facts["configuration"] = answer.describe()
    facts["configuration_confirmed"] = answer.confirmed
    survey = gyro.detect(timeout_s=LISTEN_S + 2.0)     # faults on a type or rate mismatch
    facts["datagram"] = survey.describe()
    facts["counter_step"] = survey.counter_step
    facts["sample_rate_hz_by_counter"] = survey.sample_rate_hz
    block = gyro.read_samples(max(10, int(round(sample_rate_hz * LISTEN_S))),
                              timeout_s=LISTEN_S + 2.0)
    facts["frames_valid"] = len(block)
    facts["crc_errors"] = block.crc_errors
    facts["lost_frames"] = block.lost_frames
    facts["garbage_bytes"] = block.garbage_bytes
    statuses = {"gyro": block.status}
    channels = block.channels
    if channels is not None:
        statuses.update({"accelerometers": channels.acc_status, "inclinometers": channels.incl_status})
    for sensor, status in statuses.items():
        if status is None:
            continue
        seen, flagged = _bits(status)
        facts[f"{sensor}_status_bits_seen"] = f"0x{seen:02X}"
        if seen:
            problems.append(f"{sensor} status byte nonzero in {flagged} of {len(status)} "
                            f"datagrams (bits 0x{seen:02X}, TS1524 Table 5-23)")
    xyz = block.rate_xyz if block.rate_xyz is not None else np.asarray(block.rate)[:, None]
    facts["gyro_mean"] = _means(xyz)
    if channels is not None:                       # only what the datagram carries
        for name, values in (("accelerometer_mean_g", channels.acc_g),
                             ("inclinometer_mean_g", channels.incl_g)):
            if values is not None:
                facts[name] = _means(values)
    if block.crc_errors or block.lost_frames:
        problems.append(f"{block.crc_errors} CRC error(s), {block.lost_frames} lost frame(s) "
                        f"in {len(block)} datagrams")
    return facts, problems
