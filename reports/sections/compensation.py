"""results.json ``compensation``, typed: bias and SF against temperature, and their tables.

Each table (``analysis/thermal/compensation.py``) is kept as the object that made it, so the
uncertainty of its entries (:mod:`gyrocal.reports.sections.uncertainty`) is carried
through the very same function, not guessed back from its JSON.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from gyrocal.analysis.thermal.compensation import CompensationTable
from gyrocal.metrology.gum import Uncertainty

#: the tables of one quantity: "piecewise_linear" / "polynomial" → the table (None below 3 points)
Tables = Mapping[str, CompensationTable | None]
#: each table entry's (temp_c, uncertainty), by quantity and table
TableUncertainty = Mapping[str, Mapping[str, tuple[tuple[float, Uncertainty], ...]]]


def table_json(table: CompensationTable,
               entries: tuple[tuple[float, Uncertainty], ...] | None) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": table.kind, "points": table.to_pairs(),
                           "residual_rms": table.residual_rms,
                           "loo_residual_rms": table.loo_residual_rms,
                           "loo_residual_max": table.loo_residual_max,
                           "coefficients": table.coefficients}
    if entries is not None:
        out["uncertainty"] = [{"temp_c": t, "value": u.value} | u.to_json() for t, u in entries]
    return out


@dataclass(frozen=True)
class CompensationResults:
    """(temp_c, value) points and tables of ``bias_dph`` and ``sf`` (the results.json names)."""

    bias_dph_vs_temp: tuple[tuple[float, float], ...]
    sf_vs_temp: tuple[tuple[float, float], ...]
    tables: Mapping[str, Tables]          # "bias_dph" / "sf" → its tables

    def to_json(self, u: TableUncertainty | None = None) -> dict[str, Any]:
        u = u or {}
        return {"bias_dph_vs_temp": [list(p) for p in self.bias_dph_vs_temp],
                "sf_vs_temp": [list(p) for p in self.sf_vs_temp],
                "tables": {quantity: {kind: None if table is None else
                                      table_json(table, u.get(quantity, {}).get(kind))
                                      for kind, table in tables.items()}
                           for quantity, tables in self.tables.items()}}
