"""discrepancy.html: the story in plots, one self-contained file.

QA reads this to decide whether to trust the updated model, so it shows the
evidence in the order of the argument: where model and data disagreed
(residual against time with the procedure's steps shaded, segment means
with their noise band, residual against each input), what was named and how
sure the workflow is (scores against the calibrated threshold, look-alikes
with probabilities, the separating experiment), and the gap before and after
beside the noise floor (segment means, spectrum, Allan deviation). Figures
are embedded as base64 PNG; every string from the user (model name, log
path, segment labels) goes through jinja2's autoescape.
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass
from pathlib import Path

import jinja2
import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from gyrocal.analysis.allan.deviation import overlapping_adev
from gyrocal.analysis.discrepancy.gap import FLOOR_PROBABILITY, Metric, allan_taus_m
from gyrocal.analysis.discrepancy.workflow import ALPHA, DiscrepancyResult
from gyrocal.models.effects import EFFECTS

_TEMPLATE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>Discrepancy: {{ model_name }}</title>
<style>
body { font-family: sans-serif; max-width: 1100px; margin: 2em auto; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0; }
td, th { border: 1px solid #bbb; padding: 3px 8px; text-align: left; }
td.num { white-space: nowrap; }
pre { background: #f4f4f4; padding: 0.6em; white-space: pre-wrap; overflow-wrap: anywhere; }
.passes { display: flex; flex-wrap: wrap; gap: 0 2em; align-items: flex-start; }
.effect-gaps { display: flex; flex-wrap: wrap; gap: 1em; }
figure.effect-gap { margin: 0; border: 1px solid #ddd; padding: 0.4em; }
figure.effect-gap img { display: block; width: 320px; }
figcaption { font-size: 0.9em; max-width: 320px; }
.verdict { font-size: 1.2em; padding: 0.5em; background: #eef; }
img { max-width: 100%; }
</style></head><body>
<h1>Model vs measured data</h1>
<p>Model: <b>{{ model_name }}</b> &middot; measured: <code>{{ source }}</code></p>
<p class="verdict">{{ verdict }}</p>

<h2>1. Where they disagree</h2>
<p>Residual = measured − refitted model (input-referred, deg/h), bin means; shading marks the
procedure's steps (blue: temperature ramps, grey: table moving). Segment means with their
±2σ noise band under the noise model.</p>
<img src="data:image/png;base64,{{ fig_time }}" alt="residual against time">
<p>Segment means of the residual (before) against the inputs: what the disagreement follows.</p>
<img src="data:image/png;base64,{{ fig_inputs }}" alt="residual against inputs">

<h2>2. What was named</h2>
{% if found %}
<table id="named"><tr><th>effect</th><th>parameters</th><th>probability</th><th>score</th><th>threshold</th><th>look-alikes</th></tr>
{% for f in found %}
<tr><td>{{ f.name }}</td>
<td>{% for k, v in f.parameters.items() %}{{ k }} = {{ "%.4g"|format(v) }} {{ param_unit(f.name, k) }}<br>{% endfor %}</td>
<td>{{ "%.2f"|format(f.probability) }}</td><td>{{ "%.1f"|format(f.score) }}</td>
<td>{{ "%.2f"|format(f.threshold) }}</td>
<td>{% for a in f.look_alikes %}{{ a.name }} ({{ "%.2f"|format(a.probability) }})<br>{% endfor %}</td></tr>
{% endfor %}</table>
{% for f in found if f.separating_experiment %}
<p>Experiment that would separate <b>{{ f.name }}</b> from its look-alikes (procedure fragment):</p>
<pre class="experiment">{{ f.separating_experiment }}</pre>
{% endfor %}
{% else %}
<p>No catalogue effect passed the threshold.</p>
{% endif %}
<p>Scores are −log10 of each effect's likelihood-gain tail probability; the threshold is the
{{ "%.0f"|format(100 * (1 - alpha)) }} % quantile of the best score over the whole library on
effect-free data simulated from the refitted model and the noise model.</p>
<div class="passes">{% for it in iterations %}
<div><p>Pass {{ loop.index }}: threshold {{ "%.2f"|format(it.threshold) }}, accepted: {{ it.accepted or "none" }}</p>
<table><tr><th>effect</th><th>score</th><th>Δχ²</th></tr>
{% for name, score in it.ranked %}<tr><td>{{ name }}</td><td>{{ "%.2f"|format(score) }}</td>
<td>{{ "%.1f"|format(it.delta[name]) }}</td></tr>{% endfor %}</table></div>
{% endfor %}</div>
{% if unexplained %}<p><b>Unexplained remainder:</b> {{ where }}</p>{% endif %}

<h2>3. The gap before and after</h2>
{% if effect_gaps %}
<p>Each named effect's gap in the metric where that effect lives (its own segments, the short-τ
Allan deviation for quantization, the spectrum for interference, the Allan curve for a Markov
bias): before (input model, refitted), after (updated model), and the noise floor: the level
that metric stays at or below under noise alone (effect-free residuals through the same refit)
{{ "%.0f"|format(100 * floor_probability) }} % of the time.</p>
<div class="effect-gaps">{% for g in effect_gaps %}
<figure class="effect-gap" data-effect="{{ g.effect }}" title="{{ g.label }}">
<img src="data:image/png;base64,{{ g.png }}" alt="{{ g.effect }}: its gap before and after">
<figcaption><b>{{ g.effect }}</b>, its own gap in {{ g.unit }}: before {{ "%.3g"|format(g.metric.before) }},
after {{ "%.3g"|format(g.metric.after) }}, noise floor ({{ "%.0f"|format(100 * g.metric.floor_probability) }} % point of noise alone) {{ "%.3g"|format(g.metric.noise_floor) }}</figcaption></figure>{% endfor %}</div>
{% endif %}
<table id="gap-metrics"><tr><th>metric</th><th>unit</th><th>before</th><th>after</th><th>noise floor ({{ "%.0f"|format(100 * floor_probability) }} % point of noise alone)</th></tr>
{% for name, m in metrics %}{% set label, unit = metric_label(name, m) %}
<tr><td>{{ label }} <code>{{ name }}</code>{% if name == primary %} (primary){% endif %}{% if m.description and m.description != label %}<br><small>{{ m.description }}</small>{% endif %}</td><td>{{ unit }}</td>
<td class="num">{{ "%.4g"|format(m.before) }}</td><td class="num">{{ "%.4g"|format(m.after) }}</td>
<td class="num">{{ "%.4g"|format(m.noise_floor) }}</td></tr>{% endfor %}</table>
<img src="data:image/png;base64,{{ fig_gap }}" alt="spectrum and Allan deviation">
<h3>Notes</h3>
<ul>{% for n in notes %}<li>{{ n }}</li>{% endfor %}</ul>
</body></html>
"""


#: the gap metrics (gap.METRIC_NAMES) for people: what each measures, and its unit
METRIC_LABELS = {
    "g1_segment_mean": ("G1, mean of (segment mean / its standard error)²",
                        "dimensionless, ≈ 1 when the model fits"),
    "segment_mean_rms_dph": ("RMS of the segment means", "deg/h"),
    "allan_mismatch": ("Allan mismatch, RMS over τ of ln(residual ADEV / noise-model ADEV)",
                       "natural log of a ratio, 0 when they agree"),
    "spectrum_peak": ("largest spectral line", "× the noise PSD"),
}
#: the unit in running text (the verdict line)
METRIC_UNITS = {"g1_segment_mean": "", "segment_mean_rms_dph": " deg/h",
                "allan_mismatch": " (ln ratio)", "spectrum_peak": " × noise PSD"}


def _png(fig: Figure) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _shade(ax, result: DiscrepancyResult, t_bins: np.ndarray) -> None:
    rate = result.signals["table rate (deg/s)"]
    trend = result.signals["sensor temperature rate (degC/min)"]
    for mask, colour in ((np.abs(trend) > 0.05, "#cde"), (np.abs(rate) > 1e-3, "#ddd")):
        edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(int), [0]))))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            ax.axvspan(t_bins[a], t_bins[b - 1], color=colour, lw=0, zorder=0)


def _fig_time(result: DiscrepancyResult) -> str:
    t = result.bins.centre_s
    geometry = result.geometry
    fig = Figure(figsize=(11, 6))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, resid, title in ((axes[0], result.resid_before_bins, "before (input model, refitted)"),
                             (axes[1], result.resid_after_bins, "after (updated model, refitted)")):
        _shade(ax, result, t)
        ax.plot(t, resid, ".", ms=2, color="#888", label="bin means")
        means = geometry.means(resid)
        band = 2.0 * geometry.stderr_dph
        spans = [(t[sel][0], t[sel][-1]) for sel in (geometry.seg_of_bin == k for k in range(len(means)))]
        # one collection each, not an artist per segment (an overnight run has ~300 segments)
        ax.hlines(means, [a for a, _ in spans], [b for _, b in spans], color="C3", lw=2)
        boxes = [[(a, -w), (b, -w), (b, w), (a, w)] for (a, b), w in zip(spans, band, strict=True)]
        ax.add_collection(PolyCollection(boxes, facecolors="C2", alpha=0.25, linewidths=0))
        ax.set_ylabel("residual (deg/h)")
        ax.set_title(title)
        spread = np.percentile(np.abs(resid), 99.5)
        ax.set_ylim(-1.5 * spread, 1.5 * spread)
    axes[1].set_xlabel("time (s)")
    return _png(fig)


def _fig_inputs(result: DiscrepancyResult) -> str:
    geometry = result.geometry
    means = geometry.means(result.resid_before_bins)
    fig = Figure(figsize=(11, 6))
    axes = fig.subplots(2, 3)
    for ax, (name, values) in zip(axes.ravel(), result.signals.items(), strict=False):
        x = geometry.means(values)
        ax.errorbar(x, means, yerr=2.0 * geometry.stderr_dph, fmt="o", ms=3, color="C0")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(name)
        ax.set_ylabel("segment mean (deg/h)")
    fig.tight_layout()
    return _png(fig)


def _fig_gap(result: DiscrepancyResult) -> str:
    """Spectra before and after in panels of their own (drawn in one, the after trace hid
    the before one), on the same axes so they compare; the Allan deviations beside them."""
    fig = Figure(figsize=(11, 6.5))
    grid = fig.add_gridspec(2, 2)
    spectra = [fig.add_subplot(grid[0, 0])]
    spectra.append(fig.add_subplot(grid[1, 0], sharex=spectra[0], sharey=spectra[0]))
    for ax, scan, label, colour in ((spectra[0], result.scan_before, "before", "C3"),
                                    (spectra[1], result.scan_after, "after", "C0")):
        if scan is not None:
            ax.semilogy(scan.f_hz, scan.ratio, lw=0.6, color=colour, label=label)
        ax.set_ylabel("periodogram / noise PSD")
        ax.set_title(f"residual spectrum {label} (full rate)")
    spectra[1].set_xlabel("frequency (Hz)")
    ax = fig.add_subplot(grid[:, 1])
    m = allan_taus_m(result.bins.n_bins)
    fs = 1.0 / result.bins.width_s
    for resid, label, colour in ((result.resid_before_bins, "residual before", "C3"),
                                 (result.resid_after_bins, "residual after", "C0")):
        a = overlapping_adev(resid, fs, m=m, confidence=None)
        ax.loglog(a.tau_s, a.adev, "o-", color=colour, label=label, ms=3)
    tau = m / fs
    ax.loglog(tau, result.noise_before.allan_deviation_dph(tau), "k--", label="noise model (before)")
    ax.loglog(tau, result.noise.model.allan_deviation_dph(tau), "k-", lw=0.8, label="noise model (after)")
    ax.set_xlabel("tau (s)")
    ax.set_ylabel("Allan deviation (deg/h)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def metric_label(name: str, metric) -> tuple[str, str]:
    """(what the metric measures, its unit): METRIC_LABELS for the whole-record metrics, the
    metric's own description and unit for each named effect's (own_gap.py)."""
    return METRIC_LABELS.get(name, (metric.description or name, metric.unit))


def _param_unit(effect: str, key: str) -> str:
    """An effect parameter's unit, from the catalogue (models/effects.py)."""
    definition = EFFECTS.get(effect)
    param = next((p for p in definition.params if p.key == key), None) if definition else None
    return param.unit if param is not None else ""


@dataclass(frozen=True)
class EffectGapPanel:
    """One named effect's gap, drawn in a figure of its own: in one shared image the panels
    were squeezed side by side and a reader could not tell one effect's bars from another's."""

    effect: str
    label: str
    unit: str
    metric: Metric
    png: str


def _effect_gap_panels(result: DiscrepancyResult) -> list[EffectGapPanel]:
    """Each named effect's own metric before, after and at the noise floor, with its unit."""
    panels = []
    for effect, key in result.effect_gaps.items():
        if key not in result.metrics:
            continue
        m = result.metrics[key]
        label, unit = metric_label(key, m)
        fig = Figure(figsize=(4.0, 3.2))
        ax = fig.subplots()
        ax.bar(["before", "after"], [m.before, m.after], color=["C3", "C0"])
        ax.axhline(m.noise_floor, color="k", ls="--", lw=1, label=f"noise floor ({100 * m.floor_probability:.0f} % point)")
        ax.axhline(2.0 * m.noise_floor, color="k", ls=":", lw=0.8, label="2 × floor")
        ax.set_title(effect, fontsize=10)
        ax.set_ylabel(f"its own gap ({unit})", fontsize=8)
        ax.legend(fontsize=7)
        fig.tight_layout()
        panels.append(EffectGapPanel(effect, label, unit, m, _png(fig)))
    return panels


def verdict(result: DiscrepancyResult) -> str:
    gap = result.metrics[result.primary]
    parts = []
    if result.found:
        parts.append("Found: " + ", ".join(f"{f.name} (p = {f.probability:.2f})" for f in result.found) + ".")
    else:
        parts.append("No catalogue effect is needed to explain the data." if not result.unexplained
                     else "No catalogue effect explains the disagreement.")
    if result.unexplained:
        parts.append("Structure remains that no catalogue effect explains: " + result.where + ".")
    label, unit = metric_label(result.primary, gap)
    unit = METRIC_UNITS.get(result.primary, f" {unit}")
    parts.append(f"Gap ({label}): {gap.before:.3g}{unit} before, {gap.after:.3g}{unit} after, "
                 f"noise floor {gap.noise_floor:.3g}{unit} (noise alone stays below it "
                 f"{100 * gap.floor_probability:.0f} % of the time).")
    return " ".join(parts)


def write_html(result: DiscrepancyResult, source: str, path: str | Path) -> Path:
    """Render the report to ``path``."""

    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    iterations = [{"threshold": it.threshold, "accepted": it.accepted, "delta": it.delta_chi2,
                   "ranked": sorted(it.scores.items(), key=lambda kv: -kv[1])}
                  for it in result.iterations]
    html = env.from_string(_TEMPLATE).render(
        model_name=result.input_model.name or "(unnamed model)", source=source,
        verdict=verdict(result), found=result.found, iterations=iterations, alpha=ALPHA,
        unexplained=result.unexplained, where=result.where, primary=result.primary,
        metrics=list(result.metrics.items()), floor_probability=FLOOR_PROBABILITY, notes=result.notes, metric_label=metric_label,
        param_unit=_param_unit,
        fig_time=_fig_time(result), fig_inputs=_fig_inputs(result), fig_gap=_fig_gap(result),
        effect_gaps=_effect_gap_panels(result),
    )
    path = Path(path)
    path.write_text(html, encoding="utf-8")
    return path
