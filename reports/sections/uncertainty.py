"""The uncertainty budget of every calibrated value of results.json, typed.

New keys only (interfaces.md: keys stay, new ones may be added): every
``scale_factor`` and ``bias`` entry, ``scale_factor_ls`` and
``bias_temperature`` get ``u``/``U``/``k``/``dof_eff``/``budget`` beside their
value, and ``uncertainty`` maps each dotted metric path (the names acceptance
limits use, e.g. ``asymmetry_ppm`` or ``nonlinearity.rms_pct``) to its budget,
which is where the decision rule (decision.py) finds U. This module computes
the budgets from the typed sections (:class:`UncertaintyBudget`); the sections'
``to_json`` put them beside their values.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from gyrocal.analysis.allan.noise_fit import TERM_NAMES
from gyrocal.analysis.thermal import compensation as comp
from gyrocal.analysis.thermal.compensation import CompensationTable
from gyrocal.metrology.gum import Contribution, EvalType, Uncertainty, combine
from gyrocal.metrology.metrics import (
    ASYMMETRY,
    BIAS_TEMPCO,
    NOISE_METRICS,
    NONLINEARITY_MAX,
    NONLINEARITY_RMS,
    SF_INSTABILITY,
    SF_LS,
    SF_LS_BIAS,
    SF_TEMPCO,
)
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
from gyrocal.reports.sections.allan import AllanSection
from gyrocal.reports.sections.bias import BiasResults, BiasSource
from gyrocal.reports.sections.compensation import CompensationResults, TableUncertainty
from gyrocal.reports.sections.sweep import SweepResults


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


@dataclass(frozen=True)
class UncertaintyBudget:
    """Every budget the report states, typed, beside the values they belong to.

    ``paths`` is results.json ``uncertainty``: each dotted metric path (the names
    acceptance limits use) and ``bias@T`` → its budget, which is where the decision
    rule (decision.py) finds U. The other fields put the same budgets beside the
    values of their sections (``to_json`` of each section).
    """

    sweep: Mapping[float, Mapping[str, Uncertainty]]     # setpoint → figure → budget
    bias: Mapping[float, Uncertainty]                     # setpoint → bias budget
    bias_slope: Uncertainty | None                        # bias_temperature
    compensation: TableUncertainty                        # quantity → table → entries
    allan: Mapping[str, Uncertainty] | None               # allan.fit key → budget
    paths: Mapping[str, Uncertainty]
    inputs: TypeB

    def paths_json(self) -> dict[str, Any]:
        return {path: {"value": u.value} | u.to_json() for path, u in self.paths.items()}


def uncertainty_budget(sweep: SweepResults, bias: BiasResults,
                       compensation: CompensationResults, allan: AllanSection | None,
                       steps: list[StepMean], station: Mapping[str, Any], nominal_sf: float,
                       notes: list[str]) -> UncertaintyBudget:
    """The budgets of the figures build.py computed, from the same step means."""
    type_b = TypeB.from_station(station.get("uncertainty"))
    if type_b.assumed:
        notes.append("uncertainty: the station does not declare " + ", ".join(type_b.assumed)
                     + "; the defaults of metrology/uncertainty.py are assumed (see "
                       "uncertainty_inputs)")
    sweeps, holds = _group_means(steps)
    per_temp = {e.temp_c: sweep_uncertainty(sweeps[e.temp_c], type_b) for e in sweep.entries}
    paths = _sweep_paths(sweep, per_temp)
    if len(per_temp) >= 2 and sweep.sf_temperature is not None:
        all_dwells = [m for t in sorted(per_temp) for m in sweeps[t]]
        found = sf_temperature_uncertainty(all_dwells, type_b, sweep.reference_temp_c)
        paths.update({m.key: found[m.field] for m in (SF_TEMPCO, SF_INSTABILITY)})
    latitude = (station.get("site") or {}).get("latitude_deg")
    bias_u = _bias_budgets(bias, per_temp, sweeps, holds, latitude, type_b, nominal_sf, notes)
    paths.update({f"bias@{t:g}": u for t, u in bias_u.items()})
    slope = None
    if len(bias_u) >= 2 and bias.sensitivity_dph_per_c is not None:
        temps = sorted(bias_u)
        slope = slope_uncertainty(temps, [bias_u[t] for t in temps], type_b, "bias")
        paths[BIAS_TEMPCO.key] = slope
    allan_u = None if allan is None else allan_term_budgets(allan)
    paths.update({NOISE_METRICS[name].key: u for name, u in (allan_u or {}).items()})
    return UncertaintyBudget(per_temp, bias_u, slope,
                             _compensation_budgets(compensation, sweep, per_temp, bias, bias_u),
                             allan_u, paths, type_b)


def _group_means(steps: list[StepMean]) -> tuple[dict[float, list[MeanU]],
                                                 dict[float, list[MeanU]]]:
    """Dwell means by setpoint, static/allan hold means by setpoint (finite u and ν only)."""
    usable = [s for s in steps if math.isfinite(s.mean.u) and math.isfinite(s.mean.dof)]
    sweeps: dict[float, list[MeanU]] = defaultdict(list)
    holds: dict[float, list[MeanU]] = defaultdict(list)
    for s in usable:
        if s.kind == "dwell":
            sweeps[s.mean.temp_c].append(s.mean)
        elif s.kind in HOLD_KINDS:
            holds[s.mean.temp_c].append(s.mean)
    return sweeps, holds


def _compensation_budgets(compensation: CompensationResults, sweep: SweepResults,
                          per_temp: Mapping[float, Mapping[str, Uncertainty]],
                          bias: BiasResults, bias_u: Mapping[float, Uncertainty]
                          ) -> TableUncertainty:
    """u/U/k/budget of every compensation-table entry (``tables.*.*.uncertainty``).

    An entry is a linear function of the per-temperature points (the piecewise table's
    nodes are the points; the polynomial's are its fitted values), so its budget is the
    points' budgets carried through that map, taken from the table maker itself
    (``analysis/thermal/compensation.py`` applied to unit vectors). A budget line with the same
    name in several points - the table's rate scale error, the site latitude - is one
    input common to them (fully correlated), the others are each point's own.
    """
    sources = {
        "sf": [(e.temp_c, e.result.sf, per_temp[e.temp_c]["sf"]) for e in sweep.entries
               if e.temp_c in per_temp and per_temp[e.temp_c]["sf"].budget],
        "bias_dph": [(e.temp_c, e.bias_dph, bias_u[e.temp_c]) for e in bias.entries
                     if e.temp_c in bias_u and bias_u[e.temp_c].budget],
    }
    out: dict[str, dict[str, tuple[tuple[float, Uncertainty], ...]]] = {}
    for quantity, points in sources.items():
        for kind, table in (compensation.tables.get(quantity) or {}).items():
            if table is None or len(points) != len(table.points):
                continue
            entries = table_entry_uncertainty([t for t, _, _ in points],
                                              [v for _, v, _ in points],
                                              [u.budget for _, _, u in points],
                                              _table_maker(table))
            out.setdefault(quantity, {})[kind] = tuple(entries)
    return out


def _table_maker(table: CompensationTable):
    """The function of analysis/thermal/compensation.py that made ``table`` (same degree)."""
    if not table.coefficients:
        return comp.piecewise_linear
    degree = len(table.coefficients) - 1
    return lambda temps, values: comp.polynomial(temps, values, degree=degree)


def table_entry_uncertainty(temps: list[float], values: list[float],
                            budgets: list[tuple[Contribution, ...]], make
                            ) -> list[tuple[float, Uncertainty]]:
    """(temp, Uncertainty) of each entry of the table ``make(temps, values)``."""
    n = len(temps)
    eye = np.eye(n)
    # h[i, j]: how entry i moves with point j (the table is linear in its points)
    h = np.array([[p[1] for p in make(temps, eye[j]).points] for j in range(n)]).T
    lines: dict[str, Contribution] = {}
    sensitivity: dict[str, np.ndarray] = {}
    for j, budget in enumerate(budgets):
        for line in budget:
            lines.setdefault(line.name, line)
            sensitivity.setdefault(line.name, np.zeros(n))[j] += float(line.sensitivity)
    out = []
    for i, (temp_c, value) in enumerate(make(temps, values).points):
        contributions = []
        for name, line in lines.items():
            c = float(h[i] @ sensitivity[name])
            contributions.append(replace(line, sensitivity=c,
                                         u_contribution=abs(c) * line.u_input))
        out.append((float(temp_c), combine(value, contributions)))
    return out


def allan_term_budgets(allan: AllanSection) -> dict[str, Uncertainty]:
    """u/U/k/budget of each fitted noise term (``allan.uncertainty`` and the paths map).

    u is the term's standard error from the weighted least-squares fit of the Allan
    variance (weights from the Greenhall equivalent degrees of freedom), ν the fit's
    degrees of freedom; the 68 % intervals already reported stay beside them. A term
    fitted at zero keeps u = its upper-bound scale: a coefficient cannot be negative.
    """
    dof = float(allan.fit.dof or math.inf)
    out: dict[str, Uncertainty] = {}
    for name in TERM_NAMES:
        term = getattr(allan.fit, name)
        value, stderr = term.value, term.stderr
        if not isinstance(value, (int, float)) or not isinstance(stderr, (int, float)) \
                or not math.isfinite(stderr) or stderr <= 0:
            continue
        line = Contribution(f"{name}: WLS fit of the Allan variance", "analysis/allan/noise_fit.py "
                            "(EDF-weighted least squares)", EvalType.A, "normal", stderr, 1.0,
                            stderr, dof)
        out[name] = combine(float(value), [line])
    return out


def _sweep_paths(sweep: SweepResults, per_temp: Mapping[float, Mapping[str, Uncertainty]]
                 ) -> dict[str, Uncertainty]:
    """The single-number sweep figures: budgets of the temperature each was taken from."""
    paths: dict[str, Uncertainty] = {}
    ref, rms, worst, asym = sweep.reference, sweep.worst_rms, sweep.worst_max, \
        sweep.largest_asymmetry
    if ref is None or rms is None or worst is None or asym is None:
        return paths
    paths[SF_LS.key] = per_temp[ref.temp_c]["sf"]
    paths[SF_LS_BIAS.key] = per_temp[ref.temp_c]["bias"]
    paths[NONLINEARITY_RMS.key] = per_temp[rms.temp_c]["nonlinearity_rms_pct"]
    paths[NONLINEARITY_MAX.key] = per_temp[worst.temp_c]["nonlinearity_max_ppm_fs"]
    paths[ASYMMETRY.key] = per_temp[asym.temp_c]["asymmetry_ppm"]
    return paths


def _bias_budgets(bias: BiasResults, per_temp: Mapping[float, Mapping[str, Uncertainty]],
                  sweeps: dict[float, list[MeanU]], holds: dict[float, list[MeanU]],
                  latitude: float | None, type_b: TypeB, nominal_sf: float, notes: list[str]
                  ) -> dict[float, Uncertainty]:
    out = {}
    for point in bias.entries:
        temp = point.temp_c
        if point.source is BiasSource.STATIC and holds.get(temp):
            sf = per_temp.get(temp, {}).get("sf")
            if sf is None:
                sf = Uncertainty(nominal_sf, 0.0, math.inf, 1.96, ())
                notes.append(f"uncertainty of bias at {temp:g} °C: the nominal scale factor's "
                             "uncertainty is not known and is taken as 0")
            unc = bias_uncertainty_static(_pooled_hold(holds[temp]), sf, latitude, type_b)
        elif sweeps.get(temp):
            unc = bias_uncertainty_sweep(sweeps[temp], latitude, type_b)
        else:
            continue
        out[temp] = unc
    return out
