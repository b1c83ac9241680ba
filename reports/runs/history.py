"""One gyro across its calibrations: the table, the drift test and the trend plot.

Drift is judged against the unit's first calibration in the database: a
later value differs beyond its uncertainty when |v − v₀| exceeds the
expanded uncertainty of the difference, √(U² + U₀²) (with U = 2u where only
the standard uncertainty is known). Without an uncertainty nothing is
flagged: a drift claim needs one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gyrocal.metrology.metrics import TRENDS

COVERAGE_K = 2.0

#: what the table and plot show, in this order (others stay in the database): the catalogue's
SHOWN = tuple(TRENDS)
#: how the plot labels each metric: words and the unit
LABELS = TRENDS


@dataclass(frozen=True)
class Point:
    run_id: str
    date: str
    value: float
    U: float | None          # noqa: N815 - expanded uncertainty, GUM's symbol
    drift: bool


def expanded(u: float | None, U: float | None) -> float | None:  # noqa: N803
    if U is not None:
        return U
    return None if u is None else COVERAGE_K * u


def trends(metrics: list[str], runs: list[dict[str, Any]]) -> dict[str, list[Point]]:
    out: dict[str, list[Point]] = {}
    for metric in [m for m in SHOWN if m in metrics]:
        points: list[Point] = []
        base: tuple[float, float | None] | None = None
        for run in runs:
            if metric not in run["values"]:
                continue
            value, u, U = run["values"][metric]  # noqa: N806
            big_u = expanded(u, U)
            drift = False
            if base is None:
                base = (value, big_u)
            elif big_u is not None and base[1] is not None:
                drift = abs(value - base[0]) > math.hypot(big_u, base[1])
            points.append(Point(run["run_id"], str(run["started_at"])[:19], value, big_u, drift))
        out[metric] = points
    return out


def history_table(serial: str, series: dict[str, list[Point]]) -> str:
    runs: list[tuple[str, str]] = []
    for points in series.values():
        for p in points:
            if (p.date, p.run_id) not in runs:
                runs.append((p.date, p.run_id))
    runs.sort()
    names = list(series)
    rows = [["date (UTC)", "run id", *names]]
    for date, run_id in runs:
        row = [date.replace("T", " "), run_id]
        for name in names:
            point = next((p for p in series[name] if p.run_id == run_id), None)
            if point is None:
                row.append("-")
                continue
            text = f"{point.value:.6g}" + ("" if point.U is None else f" ± {point.U:.2g}")
            row.append(text + (" *" if point.drift else ""))
        rows.append(row)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    title = (f"history of {serial}: {len(runs)} calibrations (± expanded uncertainty, "
             f"k={COVERAGE_K:g} where only u is known; * drift beyond it since the first)")
    return "\n".join([title] + [" | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True))
                                 .rstrip() for r in rows])


def history_plot(serial: str, series: dict[str, list[Point]], path: Path) -> Path:
    # Figure draws without pyplot's global backend: nothing in the process has its backend
    # changed. The text-only runs commands need not pay for matplotlib's imports.
    from matplotlib.figure import Figure  # lazy: ~0.5 s of imports (python -X importtime)
    shown = {k: v for k, v in series.items() if v}
    fig = Figure(figsize=(8, 2.0 * max(1, len(shown))))
    axes = fig.subplots(len(shown), 1, sharex=True, squeeze=False)
    for ax, (name, points) in zip(axes[:, 0], shown.items(), strict=True):
        x = list(range(1, len(points) + 1))
        y = [p.value for p in points]
        err = [p.U or 0.0 for p in points]
        ax.errorbar(x, y, yerr=err, fmt="o-", ms=3, lw=0.8, capsize=2, color="#36c")
        drifted = [(xi, p.value) for xi, p in zip(x, points, strict=True) if p.drift]
        if drifted:
            ax.plot(*zip(*drifted, strict=True), "o", ms=9, mfc="none", mec="#c00", mew=1.5,
                    label="drift beyond U")
            ax.legend(loc="best", fontsize=7)
        if points[0].U is not None:
            ax.axhspan(points[0].value - points[0].U, points[0].value + points[0].U,
                       color="#36c", alpha=0.08)
        ax.set_ylabel(LABELS.get(name, name), fontsize=7)
        ax.tick_params(labelsize=7)
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("calibration (oldest first)")
    fig.suptitle(f"{serial}: calibration history (bars: expanded uncertainty)", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    return path
