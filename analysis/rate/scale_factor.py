"""Scale factor, asymmetry and nonlinearity at one temperature from ± rate dwells.

Two conventions coexist in the source documents and QA asks for both:
Chikovani's SF(Ω) = (V⁺ − V⁻)/(2Ω) per rate with nonlinearity σ_SF/mean·100 %
(the bias cancels in the difference), and IEEE Std 528's least-squares line
output = SF·ω + bias with nonlinearity as the largest residual relative to
full-scale output. Standard deviations use ddof = 1 (sample std).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.rate.dwell import Dwell


@dataclass(frozen=True)
class LineFit:
    """output = sf·rate + bias, least squares; residuals in output units."""

    sf: float
    bias: float
    residuals: np.ndarray


@dataclass(frozen=True)
class ScaleFactorResult:
    """Scale-factor figures at one temperature (output units per deg/s).

    ``sf`` and ``bias`` come from the least-squares line over all dwells;
    ``sf_by_rate`` maps |Ω| to (V⁺ − V⁻)/(2Ω); ``sf_plus``/``sf_minus`` are
    slopes of separate fits to the positive and negative dwells (see
    :func:`analyze_scale_factor` for the case of a single rate per sign).
    """

    temp_c: float
    sf: float
    bias: float
    sf_plus: float
    sf_minus: float
    asymmetry_ppm: float
    sf_by_rate: dict[float, float]
    nonlinearity_rms_pct: float
    nonlinearity_max_ppm_fs: float
    residuals: np.ndarray

    def to_json(self) -> dict:
        """The `scale_factor` list entry of results.json."""
        return {"temp_c": self.temp_c, "sf": self.sf, "sf_plus": self.sf_plus,
                "sf_minus": self.sf_minus}


def fit_line(rate_dps: np.ndarray, output: np.ndarray) -> LineFit:
    """Least-squares output = sf·rate + bias (IEEE Std 528)."""
    rate = np.asarray(rate_dps, dtype=float)
    out = np.asarray(output, dtype=float)
    if np.unique(rate).size < 2:
        raise ValueError(f"a line needs at least two distinct rates, got {np.unique(rate).tolist()}")
    design = np.column_stack([rate, np.ones_like(rate)])
    (sf, bias), *_ = np.linalg.lstsq(design, out, rcond=None)
    return LineFit(float(sf), float(bias), out - (sf * rate + bias))


def _slope_with_fixed_bias(rate: np.ndarray, output: np.ndarray, bias: float) -> float:
    """Least-squares slope through a known intercept."""
    return float(np.dot(rate, output - bias) / np.dot(rate, rate))


def _side_sf(rate: np.ndarray, output: np.ndarray, zero_out: np.ndarray, joint_bias: float) -> float:
    """Slope of one sign's dwells, with the zero-rate dwells when there are any."""
    side_rate = np.concatenate([rate, np.zeros(zero_out.size)])
    side_out = np.concatenate([output, zero_out])
    if np.unique(side_rate).size >= 2:
        return fit_line(side_rate, side_out).sf
    return _slope_with_fixed_bias(rate, output, joint_bias)


def per_rate_sf(dwells: Sequence[Dwell]) -> dict[float, float]:
    """(V⁺ − V⁻)/(2Ω) for every |Ω| that has both a positive and a negative dwell.

    Several dwells at the same signed rate are averaged first.
    """
    means: dict[float, list[float]] = {}
    for dwell in dwells:
        means.setdefault(float(dwell.rate_dps), []).append(dwell.output_mean)
    result = {}
    for rate in sorted({abs(r) for r in means if r > 0}):
        if -rate in means:
            v_plus = float(np.mean(means[rate]))
            v_minus = float(np.mean(means[-rate]))
            result[rate] = (v_plus - v_minus) / (2.0 * rate)
    return result


def _ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator``, NaN when the denominator is 0.

    A gyro whose output does not change with rate (saturated, dead) has a
    zero scale factor; its relative figures are undefined, and NaN lets the
    results' sanity check call the run INVALID instead of the report crashing.
    """
    denominator = float(denominator)
    return float(numerator) / denominator if denominator != 0.0 else float("nan")


def analyze_scale_factor(dwells: Sequence[Dwell]) -> ScaleFactorResult:
    """All scale-factor figures from the dwells of one temperature.

    With a single rate per sign and no zero-rate dwell, the separate + and −
    slopes are taken through the joint fit's bias: the asymmetry is then not
    observable and comes out 0 (add a zero-rate dwell or a second rate to
    observe it).
    """
    if not dwells:
        raise ValueError("no dwells given")
    temps = {d.temp_c for d in dwells}
    if len(temps) != 1:
        raise ValueError(f"dwells of one temperature expected, got temperatures {sorted(temps)}")
    rate = np.array([d.rate_dps for d in dwells], dtype=float)
    output = np.array([d.output_mean for d in dwells], dtype=float)
    line = fit_line(rate, output)
    zero_out = output[rate == 0]
    positive, negative = rate > 0, rate < 0
    if not positive.any() or not negative.any():
        raise ValueError(f"dwells at both signs of rate are needed, got rates {sorted(set(rate))}")
    sf_plus = _side_sf(rate[positive], output[positive], zero_out, line.bias)
    sf_minus = _side_sf(rate[negative], output[negative], zero_out, line.bias)
    mean_side = 0.5 * (sf_plus + sf_minus)
    asymmetry_ppm = _ratio(sf_plus - sf_minus, mean_side) * 1e6

    by_rate = per_rate_sf(dwells)
    if not by_rate:
        raise ValueError("no rate has both a positive and a negative dwell")
    values = np.array(list(by_rate.values()))
    rms_pct = _ratio(values.std(ddof=1), values.mean()) * 100.0 if values.size > 1 else 0.0
    full_scale = abs(line.sf) * float(np.max(np.abs(rate)))
    max_ppm_fs = _ratio(np.max(np.abs(line.residuals)), full_scale) * 1e6
    return ScaleFactorResult(
        temp_c=float(next(iter(temps))), sf=line.sf, bias=line.bias, sf_plus=sf_plus,
        sf_minus=sf_minus, asymmetry_ppm=float(asymmetry_ppm), sf_by_rate=by_rate,
        nonlinearity_rms_pct=rms_pct, nonlinearity_max_ppm_fs=max_ppm_fs,
        residuals=line.residuals)


def analyze_by_temperature(dwells: Sequence[Dwell]) -> list[ScaleFactorResult]:
    """:func:`analyze_scale_factor` per temperature, sorted by temperature."""
    groups: dict[float, list[Dwell]] = {}
    for dwell in dwells:
        groups.setdefault(float(dwell.temp_c), []).append(dwell)
    return [analyze_scale_factor(groups[t]) for t in sorted(groups)]
