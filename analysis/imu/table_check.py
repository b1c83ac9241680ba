"""Compensation tables checked against their own data, in sample and leave-one-out.

The gyro matrix (section.py) and the accelerometer matrix (accel_section.py)
are both a sensitivity matrix S and a bias vector b per temperature, tabled
piecewise-linearly over temperature. One owner for interpolating that table and
for the in-sample / leave-one-out check keeps the two reports' checks identical.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, TypeVar

import numpy as np

from gyrocal.analysis.thermal import compensation as comp

#: (S, b) at one temperature
Calibration = tuple[np.ndarray, np.ndarray]


class TabledFit(Protocol):
    """One temperature's matrix fit: where it was measured and its (S, b)."""

    temp_c: float
    setpoint_c: float
    sensitivity: np.ndarray


_F = TypeVar("_F", bound=TabledFit)


def interpolated(fits: Sequence[_F], bias_of: Callable[[_F], np.ndarray], temp_c: float,
                 leave_out: int | None) -> Calibration | None:
    """S and b at ``temp_c`` from the piecewise-linear tables (optionally without one point)."""
    kept = [f for k, f in enumerate(fits) if k != leave_out]
    if len(kept) < 2:
        return None
    temps = np.array([f.temp_c for f in kept])
    order = np.argsort(temps)
    temps = temps[order]

    def at(values: np.ndarray) -> np.ndarray:
        flat = values.reshape(len(temps), -1)
        return np.array([comp.interp_extrap(temps, flat[:, c], np.array([temp_c]))[0]
                         for c in range(flat.shape[1])]).reshape(values.shape[1:])
    return (at(np.array([kept[k].sensitivity for k in order])),
            at(np.array([bias_of(kept[k]) for k in order])))


def check_rows(fits: Sequence[_F], bias_of: Callable[[_F], np.ndarray],
               residual: Callable[[_F, Calibration], np.ndarray],
               summary: Callable[[np.ndarray], dict[str, Any]]) -> list[dict[str, Any]]:
    """Per temperature: ``summary`` of the (n, 3) ``residual`` of that temperature's data
    compensated with its own (S, b) ("in_sample") and with the table built without it
    ("leave_one_out"); None where there is no usable table."""
    rows = []
    for k, fit in enumerate(fits):
        row: dict[str, Any] = {"temp_c": fit.temp_c, "setpoint_c": fit.setpoint_c}
        for label, leave_out in (("in_sample", None), ("leave_one_out", k)):
            cal = (fit.sensitivity, bias_of(fit)) if leave_out is None else \
                interpolated(fits, bias_of, fit.temp_c, leave_out)
            if cal is None or not np.all(np.isfinite(cal[0])):
                row[label] = None
                continue
            row[label] = summary(residual(fit, cal))
        rows.append(row)
    return rows
