"""Puts u, U, k, dof_eff and budget beside each calibrated value of results.json.

New keys only (interfaces.md: keys stay, new ones may be added): every
``scale_factor`` and ``bias`` entry, ``scale_factor_ls`` and
``bias_temperature`` get ``u``/``U``/``k``/``dof_eff``/``budget`` beside their
value, and ``uncertainty`` maps each dotted metric path (the names acceptance
limits use, e.g. ``asymmetry_ppm`` or ``nonlinearity.rms_pct``) to its budget,
which is where the decision rule (decision.py) finds U.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyrocal.analysis.thermal import compensation as comp
from gyrocal.metrology.gum import Contribution, EvalType, Uncertainty, combine
from gyrocal.metrology.uncertainty import (
    MeanU,
    TypeB,
    bias_uncertainty_static,
    bias_uncertainty_sweep,
    sf_temperature_uncertainty,
    slope_uncertainty,
    sweep_uncertainty,
)
from gyrocal.record.logged_steps import HOLD_KINDS


@dataclass(frozen=True)
class StepMean:
    """A logged step's kind and its mean with type A uncertainty."""

    kind: str
    mean: MeanU


def _pooled_hold(holds: list[MeanU]) -> MeanU:
    """Equal-weight mean of several holds at one temperature, u and ν by WS."""
    n = len(holds)
    value = sum(h.mean for h in holds) / n
    parts = [Contribution(h.step_id, "hold", EvalType.A, "normal", h.u, 1.0 / n, h.u / n, h.dof)
             for h in holds]
    pooled = combine(value, parts)
    return MeanU(holds[0].temp_c, 0.0, value, pooled.u, pooled.dof_eff,
                 "+".join(h.step_id for h in holds))


def add_uncertainties(results: dict[str, Any], steps: list[StepMean], plan: dict[str, Any],
                      reference_temp_c: float, notes: list[str]) -> None:
    """Adds the keys above to ``results`` in place (figures already computed by build.py)."""
    station = plan.get("station") or {}
    type_b = TypeB.from_station(station.get("uncertainty"))
    if type_b.assumed:
        notes.append("uncertainty: the station does not declare " + ", ".join(type_b.assumed)
                     + "; the defaults of metrology/uncertainty.py are assumed (see "
                       "uncertainty_inputs)")
    usable = [s for s in steps if math.isfinite(s.mean.u) and math.isfinite(s.mean.dof)]
    sweeps: dict[float, list[MeanU]] = defaultdict(list)
    holds: dict[float, list[MeanU]] = defaultdict(list)
    for s in usable:
        if s.kind == "dwell":
            sweeps[s.mean.temp_c].append(s.mean)
        elif s.kind in HOLD_KINDS:
            holds[s.mean.temp_c].append(s.mean)
    paths: dict[str, Uncertainty] = {}
    per_temp: dict[float, dict[str, Uncertainty]] = {}
    for entry in results.get("scale_factor") or []:
        temp = float(entry["temp_c"])
        per_temp[temp] = sweep_uncertainty(sweeps[temp], type_b)
        entry.update(per_temp[temp]["sf"].to_json())
        entry["uncertainty"] = {k: v.to_json() for k, v in per_temp[temp].items() if k != "sf"}
    _sweep_paths(results, per_temp, paths)
    if len(per_temp) >= 2 and results.get("sf_temperature"):
        all_dwells = [m for t in sorted(per_temp) for m in sweeps[t]]
        for key, unc in sf_temperature_uncertainty(all_dwells, type_b, reference_temp_c).items():
            paths[f"sf_temperature.{key}"] = unc
    latitude = (station.get("site") or {}).get("latitude_deg")
    bias_u = _bias_entries(results, per_temp, sweeps, holds, latitude, type_b, notes)
    paths.update({f"bias@{t:g}": u for t, u in bias_u.items()})
    if len(bias_u) >= 2 and results.get("bias_temperature"):
        temps = sorted(bias_u)
        slope = slope_uncertainty(temps, [bias_u[t] for t in temps], type_b, "bias")
        paths["bias_temperature.sensitivity_dph_per_c"] = slope
        results["bias_temperature"].update(slope.to_json())
    _compensation_entries(results)
    paths.update(_allan_terms(results))
    results["uncertainty"] = {path: {"value": u.value} | u.to_json() for path, u in paths.items()}
    results["uncertainty_inputs"] = type_b.to_json()


#: results.json compensation table → (its points' list, the value key of a point)
_TABLE_SOURCES = {"sf": ("scale_factor", "sf"), "bias_dph": ("bias", "bias_dph")}


def _compensation_entries(results: dict[str, Any]) -> None:
    """u/U/k/budget of every compensation-table entry (``tables.*.*.uncertainty``).

    An entry is a linear function of the per-temperature points (the piecewise table's
    nodes are the points; the polynomial's are its fitted values), so its budget is the
    points' budgets carried through that map, taken from the table maker itself
    (``analysis/thermal/compensation.py`` applied to unit vectors). A budget line with the same
    name in several points - the table's rate scale error, the site latitude - is one
    input common to them (fully correlated), the others are each point's own.
    """
    tables = (results.get("compensation") or {}).get("tables") or {}
    for key, (source, value_key) in _TABLE_SOURCES.items():
        points = [p for p in results.get(source) or [] if p.get("budget")]
        for table in (tables.get(key) or {}).values():
            if table is None or len(points) != len(table["points"]):
                continue
            temps = [float(p["temp_c"]) for p in points]
            make = _table_maker(table)
            entries = table_entry_uncertainty(temps, [p[value_key] for p in points],
                                              [p["budget"] for p in points], make)
            table["uncertainty"] = [{"temp_c": t, "value": u.value} | u.to_json()
                                    for t, u in entries]


def _table_maker(table: dict[str, Any]):
    """The function of analysis/thermal/compensation.py that made ``table`` (same degree)."""
    if not table.get("coefficients"):
        return comp.piecewise_linear
    degree = len(table["coefficients"]) - 1
    return lambda temps, values: comp.polynomial(temps, values, degree=degree)


def table_entry_uncertainty(temps: list[float], values: list[float],
                            budgets: list[list[dict[str, Any]]], make
                            ) -> list[tuple[float, Uncertainty]]:
    """(temp, Uncertainty) of each entry of the table ``make(temps, values)``."""
    n = len(temps)
    eye = np.eye(n)
    # h[i, j]: how entry i moves with point j (the table is linear in its points)
    h = np.array([[p[1] for p in make(temps, eye[j]).points] for j in range(n)]).T
    lines: dict[str, dict[str, Any]] = {}
    sensitivity: dict[str, np.ndarray] = {}
    for j, budget in enumerate(budgets):
        for line in budget:
            name = line["name"]
            lines.setdefault(name, line)
            sensitivity.setdefault(name, np.zeros(n))[j] += float(line["sensitivity"])
    out = []
    for i, (temp_c, value) in enumerate(make(temps, values).points):
        contributions = []
        for name, line in lines.items():
            c = float(h[i] @ sensitivity[name])
            u_input = float(line["u_input"])
            contributions.append(Contribution(
                name, line["source"], EvalType(line["type"]), line["distribution"], u_input,
                c, abs(c) * u_input, math.inf if line.get("dof") is None else float(line["dof"])))
        out.append((float(temp_c), combine(value, contributions)))
    return out


def _allan_terms(results: dict[str, Any]) -> dict[str, Uncertainty]:
    """u/U/k/budget of each fitted noise term (``allan.uncertainty`` and the paths map).

    u is the term's standard error from the weighted least-squares fit of the Allan
    variance (weights from the Greenhall equivalent degrees of freedom), ν the fit's
    degrees of freedom; the 68 % intervals already reported stay beside them. A term
    fitted at zero keeps u = its upper-bound scale: a coefficient cannot be negative.
    """
    allan = results.get("allan")
    if not allan or not allan.get("fit_uncertainty"):
        return {}
    dof = float(allan.get("fit_dof") or math.inf)
    out: dict[str, Uncertainty] = {}
    for name, est in allan["fit_uncertainty"].items():
        value = (allan.get("fit") or {}).get(name) if "." not in name else None
        stderr = est.get("stderr")
        if not isinstance(value, (int, float)) or not isinstance(stderr, (int, float)) \
                or not math.isfinite(stderr) or stderr <= 0:
            continue
        line = Contribution(f"{name}: WLS fit of the Allan variance", "analysis/allan/noise_fit.py "
                            "(EDF-weighted least squares)", EvalType.A, "normal", stderr, 1.0,
                            stderr, dof)
        out[f"allan.fit.{name}"] = combine(float(value), [line])
    allan["uncertainty"] = {name.removeprefix("allan.fit."): {"value": u.value} | u.to_json()
                            for name, u in out.items()}
    return out


def _sweep_paths(results: dict[str, Any], per_temp: dict[float, dict[str, Uncertainty]],
                 paths: dict[str, Uncertainty]) -> None:
    """The single-number sweep figures: budgets of the temperature each was taken from."""
    if not per_temp:
        return
    ls = results.get("scale_factor_ls")
    if ls:
        ref = per_temp[float(ls["temp_c"])]
        paths["scale_factor_ls.sf"], paths["scale_factor_ls.bias"] = ref["sf"], ref["bias"]
        ls.update(ref["sf"].to_json())
    entries = results.get("scale_factor") or []
    for path, key in (("nonlinearity.rms_pct", "rms_pct"),
                      ("nonlinearity.max_ppm_fs", "max_ppm_fs")):
        worst = max(entries, key=lambda e, key=key: e["nonlinearity"][key])
        paths[path] = per_temp[float(worst["temp_c"])][f"nonlinearity_{key}"]
    chosen = max(entries, key=lambda e: abs(e["asymmetry_ppm"]))
    paths["asymmetry_ppm"] = per_temp[float(chosen["temp_c"])]["asymmetry_ppm"]


def _bias_entries(results: dict[str, Any], per_temp: dict[float, dict[str, Uncertainty]],
                  sweeps: dict[float, list[MeanU]], holds: dict[float, list[MeanU]],
                  latitude: float | None, type_b: TypeB, notes: list[str]
                  ) -> dict[float, Uncertainty]:
    out = {}
    for point in results.get("bias") or []:
        temp = float(point["temp_c"])
        if point.get("source") == "static" and holds.get(temp):
            sf = per_temp.get(temp, {}).get("sf")
            if sf is None:
                nominal = float((results.get("unit_under_test") or {}).get(
                    "nominal_scale_factor") or 1.0)
                sf = Uncertainty(nominal, 0.0, math.inf, 1.96, ())
                notes.append(f"uncertainty of bias at {temp:g} °C: the nominal scale factor's "
                             "uncertainty is not known and is taken as 0")
            unc = bias_uncertainty_static(_pooled_hold(holds[temp]), sf, latitude, type_b)
        elif sweeps.get(temp):
            unc = bias_uncertainty_sweep(sweeps[temp], latitude, type_b)
        else:
            continue
        point.update(unc.to_json())
        out[temp] = unc
    return out
