"""What a STIM300 datagram carries besides the rates: accelerometers, inclinometers, temperatures.

Typed, one field per quantity, so the IMU work and the logger never guess
at keys. A field is None when the configured datagram does not carry it
(TS1524 Table 5-21). :meth:`SensorChannels.columns` is the one place that
names the logged columns.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

AXES = ("x", "y", "z")


@dataclass
class SensorChannels:
    """Per-sample values of one block of datagrams (n rows each)."""

    acc_g: np.ndarray | None = None              # (n, 3) accelerometers, g
    acc_status: np.ndarray | None = None         # uint8 status byte of the accelerometers
    incl_g: np.ndarray | None = None             # (n, 3) inclinometers, g
    incl_status: np.ndarray | None = None
    gyro_temp_c: np.ndarray | None = None        # (n, 3) temperature of each gyro, °C
    gyro_temp_status: np.ndarray | None = None
    acc_temp_c: np.ndarray | None = None         # (n, 3) temperature of each accelerometer
    acc_temp_status: np.ndarray | None = None
    incl_temp_c: np.ndarray | None = None        # (n, 3) temperature of each inclinometer
    incl_temp_status: np.ndarray | None = None
    pps: np.ndarray | None = None                # raw 24-bit PPS field (unit set in the unit)
    pps_status: np.ndarray | None = None

    @property
    def rows(self) -> int:
        """Samples held (0 when the datagram carries none of these channels)."""
        names = self.present()
        return 0 if not names else int(len(getattr(self, names[0])))

    def present(self) -> list[str]:
        return [f.name for f in fields(self) if getattr(self, f.name) is not None]

    def sliced(self, selection: slice) -> SensorChannels:
        return SensorChannels(**{name: getattr(self, name)[selection] for name in self.present()})

    def columns(self) -> dict[str, np.ndarray]:
        """Logged columns: ``acc_x_g``…, ``incl_x_g``…, ``gyro_temp_x_c``…, statuses."""
        out: dict[str, np.ndarray] = {}
        for group, unit in (("acc", "g"), ("incl", "g"), ("gyro_temp", "c"), ("acc_temp", "c"),
                            ("incl_temp", "c")):
            values = getattr(self, f"{group}_{unit}")
            if values is not None:
                for axis, name in enumerate(AXES):
                    out[f"{group}_{name}_{unit}"] = np.asarray(values[:, axis], dtype=np.float64)
                out[f"{group}_status"] = np.asarray(getattr(self, f"{group}_status"), dtype=np.uint8)
        if self.pps is not None and self.pps_status is not None:
            out["pps"] = np.asarray(self.pps, dtype=np.float64)
            out["pps_status"] = np.asarray(self.pps_status, dtype=np.uint8)
        return out


def concat_channels(parts: list[SensorChannels]) -> SensorChannels:
    """Blocks joined in order (every part carries the same fields)."""
    if not parts:
        return SensorChannels()
    names = parts[0].present()
    return SensorChannels(**{name: np.concatenate([getattr(p, name) for p in parts])
                             for name in names})


#: logged column names of every channel a datagram may carry (the chunk writer's list)
CHANNEL_COLUMNS: tuple[str, ...] = tuple(
    [f"{g}_{a}_g" for g in ("acc", "incl") for a in AXES]
    + [f"{g}_{a}_c" for g in ("gyro_temp", "acc_temp", "incl_temp") for a in AXES]
    + ["pps"])
CHANNEL_STATUS_COLUMNS: tuple[str, ...] = ("acc_status", "incl_status", "gyro_temp_status",
                                           "acc_temp_status", "incl_temp_status", "pps_status")
