"""What people read for results keys: words and units (one owner for the report and the
certificate, so a key is never shown raw in one and in words in the other)."""

from __future__ import annotations

from typing import Any

from gyrocal.models.noise_terms import NOISE_TERMS

#: Allan rows: (results key, what a reader sees, unit)
ALLAN_TERMS = tuple((t.fit_key, f"{t.symbol} — {t.name}", t.unit) for t in NOISE_TERMS)

#: compensation tables (results ``compensation.tables`` keys): what they hold and their unit
#: (None: the unit under test's output units per deg/s)
COMPENSATION = {"bias_dph": ("Bias over temperature", "deg/h"),
                "sf": ("Scale factor over temperature", None)}


def output_units(results: dict[str, Any]) -> str:
    return str((results.get("unit_under_test") or {}).get("output_units") or "")


def compensation_labels(results: dict[str, Any]) -> dict[str, tuple[str, str]]:
    units = output_units(results)
    return {key: (label, unit or f"{units} per deg/s")
            for key, (label, unit) in COMPENSATION.items()}


def acceptance_unit(entry: dict[str, Any]) -> str:
    """The unit an acceptance value and limit are in. The procedure parser fills in the
    metric's unit when a limit names none (orchestrator/procedure/acceptance.py), so it is in every
    plan; a run recorded before that shows none rather than a guess."""
    return str(entry.get("unit") or "")
