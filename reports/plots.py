"""The report's figures as base64 PNG, so report.html is one self-contained file.

Matplotlib's object API with the Agg canvas (no pyplot global state: the
report is also built inside a running engine). Few figures at modest DPI
keep an overnight report inside its time budget.
"""

from __future__ import annotations

import base64
import io
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: 8 × 4.5 in at 100 dpi: 800 × 450 px, labels readable at the page's width (they were
#: 512 × 288 px, too small to read a tick label)
DPI = 100
SIZE_IN = (8.0, 4.5)


def _png(figure: Figure) -> str:
    FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    figure.tight_layout()
    figure.savefig(buffer, format="png", dpi=DPI)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _axes(title: str, xlabel: str, ylabel: str):
    figure = Figure(figsize=SIZE_IN)
    ax = figure.add_subplot()
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    return figure, ax


def sf_vs_rate(scale_factor: list[dict[str, Any]]) -> str | None:
    """(V⁺ − V⁻)/2Ω per rate, ppm from each temperature's LS SF."""
    if not scale_factor:
        return None
    figure, ax = _axes("Scale factor per rate", "|rate| (deg/s)", "SF − SF_LS (ppm)")
    for entry in scale_factor:
        pairs = entry.get("sf_by_rate") or []
        if pairs and entry.get("sf"):
            ax.plot([p[0] for p in pairs], [(p[1] / entry["sf"] - 1.0) * 1e6 for p in pairs],
                    "o-", label=f"{entry['temp_c']:g} °C")
    ax.set_xscale("log")
    ax.legend(fontsize=8)
    return _png(figure)


def nonlinearity_residuals(scale_factor: list[dict[str, Any]]) -> str | None:
    if not scale_factor:
        return None
    figure, ax = _axes("LS line residuals", "rate (deg/s)", "residual (ppm of full scale)")
    for entry in scale_factor:
        pairs = entry.get("residuals_ppm_fs") or []
        ax.plot([p[0] for p in pairs], [p[1] for p in pairs], "o-", label=f"{entry['temp_c']:g} °C")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.legend(fontsize=8)
    return _png(figure)


def _vs_temperature(title: str, ylabel: str, pairs: list[list[float]],
                    tables: dict[str, Any] | None) -> str | None:
    if not pairs:
        return None
    figure, ax = _axes(title, "temperature (°C)", ylabel)
    ax.plot([p[0] for p in pairs], [p[1] for p in pairs], "o", label="measured")
    for table in (tables or {}).values():
        if table:
            pts = table["points"]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", label=table["kind"])
    ax.legend(fontsize=8)
    return _png(figure)


def sf_vs_temperature(compensation: dict[str, Any]) -> str | None:
    return _vs_temperature("Scale factor vs temperature", "SF (output units per deg/s)",
                           compensation.get("sf_vs_temp") or [],
                           (compensation.get("tables") or {}).get("sf"))


def bias_vs_temperature(compensation: dict[str, Any]) -> str | None:
    return _vs_temperature("Bias vs temperature (Earth rate removed)", "bias (deg/h)",
                           compensation.get("bias_dph_vs_temp") or [],
                           (compensation.get("tables") or {}).get("bias_dph"))


def allan_deviation(allan: dict[str, Any] | None) -> str | None:
    """Measured ADEV with its 68 % band and the fitted noise model."""
    if not allan:
        return None
    figure, ax = _axes("Allan deviation (input-referred)", "τ (s)", "σ(τ) (deg/h)")
    tau = allan["tau_s"]
    ax.fill_between(tau, allan["adev_lo_dph"], allan["adev_hi_dph"], alpha=0.3,
                    label="68 % interval")
    ax.loglog(tau, allan["adev_dph"], ".-", label="measured")
    if allan.get("model_adev_dph"):
        ax.loglog(tau, allan["model_adev_dph"], "--", label="fitted terms")
    ax.legend(fontsize=8)
    return _png(figure)


def all_plots(results: dict[str, Any]) -> dict[str, str | None]:
    """Every figure of the report, keyed by its section."""
    compensation = results.get("compensation") or {}
    return {
        "sf_vs_rate": sf_vs_rate(results.get("scale_factor") or []),
        "nonlinearity": nonlinearity_residuals(results.get("scale_factor") or []),
        "sf_vs_temp": sf_vs_temperature(compensation),
        "bias_vs_temp": bias_vs_temperature(compensation),
        "allan": allan_deviation(results.get("allan")),
    }
