"""Two runs side by side: their metrics in one table and their curves overlaid.

Reads each run's ``report/results.json`` where it lies. The difference is
marked when it exceeds the expanded uncertainty of the difference (as in
:mod:`history`); without uncertainties it is only shown.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from gyrocal.reports.runs.database import RunsDatabaseError
from gyrocal.reports.runs.history import expanded
from gyrocal.reports.runs.metrics import metric_values


def load_results(run_dir: Path) -> dict[str, Any]:
    path = Path(run_dir) / "report" / "results.json"
    if not path.is_file():
        raise RunsDatabaseError(f"{path}: missing; build it with `gyrocal report {run_dir}`")
    try:
        return json.loads(path.read_text())
    except ValueError as exc:
        raise RunsDatabaseError(f"{path}: not valid JSON ({exc})") from None


def compare_table(a: dict[str, Any], b: dict[str, Any], label_a: str, label_b: str) -> str:
    va = {m.metric: m for m in metric_values(a)}
    vb = {m.metric: m for m in metric_values(b)}
    width = max(len(n) for n in [*va, *vb, "metric"])
    lines = [f"{'metric'.ljust(width)} | {label_a[:24]:>24} | {label_b[:24]:>24} | "
             f"{'B − A':>12} | beyond U?"]
    for name in [n for n in va if n in vb] + [n for n in vb if n not in va]:
        ma, mb = va.get(name), vb.get(name)
        cells = []
        for m in (ma, mb):
            big_u = None if m is None else expanded(m.u, m.U)
            cells.append("-" if m is None else f"{m.value:.6g}" +
                         ("" if big_u is None else f" ± {big_u:.2g}"))
        diff = beyond = ""
        if ma is not None and mb is not None:
            diff = f"{mb.value - ma.value:+.4g}"
            ua, ub = expanded(ma.u, ma.U), expanded(mb.u, mb.U)
            if ua is not None and ub is not None:
                beyond = "YES" if abs(mb.value - ma.value) > math.hypot(ua, ub) else "no"
        lines.append(f"{name.ljust(width)} | {cells[0]:>24} | {cells[1]:>24} | {diff:>12} | "
                     f"{beyond}")
    return "\n".join(lines)


def compare_plot(a: dict[str, Any], b: dict[str, Any], label_a: str, label_b: str,
                 path: Path) -> Path:
    # Figure draws without pyplot's global backend: nothing in the process has its backend
    # changed. The text-only runs commands need not pay for matplotlib's imports.
    from matplotlib.figure import Figure  # lazy: ~0.5 s of imports (python -X importtime)
    fig = Figure(figsize=(12, 3.4))
    axes = fig.subplots(1, 3)
    for results, label, color in ((a, label_a, "#36c"), (b, label_b, "#c33")):
        allan = results.get("allan") or {}
        if allan.get("tau_s"):
            axes[0].loglog(allan["tau_s"], allan["adev_dph"], color=color, lw=1, label=label)
        sf = [r for r in results.get("scale_factor") or [] if isinstance(r, dict)]
        axes[1].plot([r.get("temp_c") for r in sf], [r.get("sf") for r in sf], "o-",
                     color=color, label=label)
        bias = [r for r in results.get("bias") or [] if isinstance(r, dict)]
        axes[2].plot([r.get("temp_c") for r in bias], [r.get("bias_dph") for r in bias], "o-",
                     color=color, label=label)
    for ax, title, xl, yl in ((axes[0], "Allan deviation", "τ (s)", "σ (°/h)"),
                              (axes[1], "scale factor vs temperature", "°C", "SF"),
                              (axes[2], "bias vs temperature", "°C", "bias (°/h)")):
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(xl, fontsize=8)
        ax.set_ylabel(yl, fontsize=8)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    return path
