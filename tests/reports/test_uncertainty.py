"""GUM budgets checked against what our code did not produce.

* regression standard errors against scipy.optimize.curve_fit with known
  σ (absolute_sigma=True): the textbook (XᵀWX)⁻¹ covariance;
* coverage factors against the published Student t table (GUM Table G.2);
* Welch–Satterthwaite against GUM G.4.1's formula on a worked case;
* the propagation against a Monte Carlo (JCGM 101) for SF and its tempco;
* batch-means SEM against the analytic variance of the mean of AR(1) noise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import curve_fit

from gyrocal.analysis.rate.scale_factor import analyze_scale_factor
from gyrocal.analysis.thermal import bias as bias_mod
from gyrocal.metrology.gum import (
    batch_mean_sem,
    coverage_factor,
    monte_carlo,
    welch_satterthwaite,
)
from gyrocal.metrology.uncertainty import (
    MeanU,
    TypeB,
    mean_inputs,
    perturbed_dwells,
    rate_input,
    sf_temperature_uncertainty,
    sweep_uncertainty,
    temp_input,
)

NO_TYPE_B = TypeB(0.0, 0.0, 0.0, 0.0)
RATES = (-100.0, -30.0, -10.0, 10.0, 30.0, 100.0)


def _sweep(temp_c: float, sf: float, bias: float, u: float, seed: int) -> list[MeanU]:
    rng = np.random.default_rng(seed)
    return [MeanU(temp_c, r, sf * r + bias + u * rng.standard_normal(), u, 9.0)
            for r in RATES]


def test_sf_and_bias_u_match_scipy_curve_fit_with_known_sigma():
    means = _sweep(25.0, 1.0005, 0.003, 2e-4, seed=1)
    rate = np.array([m.rate_dps for m in means])
    out = np.array([m.mean for m in means])
    popt, pcov = curve_fit(lambda x, a, b: a * x + b, rate, out,
                           sigma=np.full(rate.size, 2e-4), absolute_sigma=True,
                           jac=lambda x, a, b: np.column_stack([x, np.ones_like(x)]))
    budget = sweep_uncertainty(means, NO_TYPE_B)
    assert budget["sf"].value == pytest.approx(popt[0], rel=1e-12)
    assert budget["sf"].u == pytest.approx(math.sqrt(pcov[0, 0]), rel=1e-6)
    assert budget["bias"].u == pytest.approx(math.sqrt(pcov[1, 1]), rel=1e-6)
    # every dwell has ν = 9 and c_i ∝ r_i (OLS slope): ν_eff = 9·(Σr²)²/Σr⁴ (GUM G.4.1)
    r = np.array(RATES)
    assert budget["sf"].dof_eff == pytest.approx(9 * (r @ r) ** 2 / np.sum(r ** 4), rel=1e-6)


def test_table_rate_accuracy_enters_sf_as_relative_rectangular():
    means = _sweep(25.0, 1.0, 0.0, 1e-9, seed=2)
    budget = sweep_uncertainty(means, TypeB(10.0, 0.0, 0.0, 0.0))
    rate_line = next(c for c in budget["sf"].budget if c.name == "table rate scale error")
    assert rate_line.u_contribution == pytest.approx(10e-6 / math.sqrt(3.0), rel=1e-6)
    assert rate_line.kind.value == "B"


@pytest.mark.parametrize(("dof", "k"), [(1, 12.71), (2, 4.30), (10, 2.23), (50, 2.01),
                                        (math.inf, 1.96)])
def test_coverage_factor_is_the_published_t_table(dof, k):
    assert coverage_factor(dof) == pytest.approx(k, abs=0.005)   # GUM Table G.2, p = 95 %


def test_welch_satterthwaite_worked_case():
    # u1 = 1 (ν = 4), u2 = 1 (ν = ∞): ν_eff = (1+1)² / (1/4) = 16
    assert welch_satterthwaite([1.0, 1.0], [4.0, math.inf]) == pytest.approx(16.0)
    assert math.isinf(welch_satterthwaite([1.0], [math.inf]))


def test_gum_matches_monte_carlo_for_sf_and_sf_tempco():
    type_b = TypeB(10.0, 0.5, 0.0, 0.0)
    sweep = _sweep(25.0, 1.0, 0.002, 3e-5, seed=3)
    inputs = mean_inputs(sweep) + [rate_input(type_b)]
    gum = sweep_uncertainty(sweep, type_b)["sf"]
    _, mc_std, lo, hi = monte_carlo(lambda x: analyze_scale_factor(perturbed_dwells(sweep, x)).sf,
                                    inputs, draws=4000, seed=1)
    assert gum.u == pytest.approx(mc_std, rel=0.06)
    # The table's rectangular rate accuracy dominates: the MC 95 % interval of a near-uniform
    # output is ±1.65u, narrower than the GUM's k = 1.96 (JCGM 101 §9.2 shows the same case),
    # so the GUM interval covers the MC one and is not grossly wider.
    assert gum.value - gum.U <= lo < hi <= gum.value + gum.U
    assert hi - lo > 0.75 * 2 * gum.U

    temps = (-20.0, 25.0, 70.0)
    means = [m for i, t in enumerate(temps)
             for m in _sweep(t, 1.0 + 20e-6 * (t - 25.0), 0.0, 3e-5, seed=10 + i)]
    gum_tc = sf_temperature_uncertainty(means, type_b, 25.0)["sensitivity_ppm_per_c"]
    tc_inputs = (mean_inputs(means) + [rate_input(type_b)]
                 + [temp_input(t, type_b) for t in temps])

    def tempco(x):
        dwells = perturbed_dwells(means, x)
        groups = [analyze_scale_factor([d for m, d in zip(means, dwells, strict=True)
                                        if m.temp_c == t]) for t in temps]
        return bias_mod.sf_temperature(groups, 25.0).sensitivity_ppm_per_c

    _, mc_tc, _, _ = monte_carlo(tempco, tc_inputs, draws=1500, seed=2)
    assert gum_tc.u == pytest.approx(mc_tc, rel=0.1)


def test_batch_means_sem_sees_correlated_noise():
    phi, n = 0.99, 200_000
    rng = np.random.default_rng(4)
    e = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = e[0] / math.sqrt(1 - phi ** 2)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    sem, dof = batch_mean_sem(x, 10)
    white = x.std(ddof=1) / math.sqrt(n)
    # AR(1): var(mean) ≈ σ²/n · (1+φ)/(1−φ), i.e. √199 ≈ 14× the white-noise SEM
    true = white * math.sqrt((1 + phi) / (1 - phi))
    assert dof == 9.0
    assert sem > 5 * white
    assert sem == pytest.approx(true, rel=0.6)


# -- coverage factors that hold (issue 11's coverage table) ---------------------------------

def test_a_dominant_rectangular_input_gets_its_own_95_percent_point() -> None:
    """One rectangular input alone: 95 % of a uniform ±a lies within 0.95·a = 1.645 u
    (GUM G.2.3), not t(∞)·u = 1.96 u; a dominant normal input keeps k ≈ 1.96."""
    from gyrocal.metrology.gum import Contribution, EvalType, combine

    rect = Contribution("rate", "station", EvalType.B, "rectangular", 1.0, 1.0, 1.0, math.inf)
    alone = combine(0.0, [rect])
    assert alone.k == pytest.approx(0.95 * math.sqrt(3.0), rel=0.01)
    normal = Contribution("noise", "data", EvalType.B, "normal", 10.0, 1.0, 10.0, math.inf)
    assert combine(0.0, [rect, normal]).k == pytest.approx(1.96, rel=0.01)
    assert combine(0.0, [rect]).k == alone.k                      # fixed seed: reproducible


def test_nonlinearity_noise_draws_are_what_the_analysis_gives() -> None:
    """The vectorised maps against analyze_scale_factor itself on the same sampled means."""
    from gyrocal.analysis.rate.dwell import Dwell
    from gyrocal.metrology.uncertainty import NOISE_BOUND_SEED, nonlinearity_noise_draws

    rates = (10.0, -10.0, 50.0, -50.0, 100.0, -100.0, 200.0, -200.0)
    means = [MeanU(25.0, r, 0.999 * r + 0.003, 2e-5 * (1 + abs(r) / 50), 9.0, f"s{r}")
             for r in rates]
    draws = nonlinearity_noise_draws(means, 0.999, draws=7)
    rng = np.random.default_rng(NOISE_BOUND_SEED)
    noise = np.column_stack([m.u * rng.standard_normal(7) for m in means])
    for j in range(7):
        result = analyze_scale_factor([Dwell(25.0, m.rate_dps, 0.999 * m.rate_dps + 0.003
                                             + noise[j, i]) for i, m in enumerate(means)])
        assert draws["nonlinearity_max_ppm_fs"][j] == pytest.approx(
            result.nonlinearity_max_ppm_fs, rel=1e-6)
        assert draws["nonlinearity_rms_pct"][j] == pytest.approx(
            result.nonlinearity_rms_pct, rel=1e-6)


def test_compensation_entries_carry_the_points_budgets_through_the_table() -> None:
    """Piecewise entries are the points (same u); polynomial entries agree with a Monte Carlo
    of numpy's polyfit over the points drawn from their budgets, a common rate-scale line
    moving all points together (fully correlated) and each point's own noise apart."""
    from gyrocal.analysis.thermal import compensation as comp
    from gyrocal.metrology.gum import Contribution, EvalType
    from gyrocal.reports.sections.uncertainty import table_entry_uncertainty

    temps = [-40.0, -10.0, 25.0, 50.0, 75.0]
    values = [0.99990, 0.99995, 1.0, 1.00004, 1.00009]
    own_u = [2e-6, 3e-6, 1.5e-6, 2.5e-6, 4e-6]
    common_u, common_c = 5.8e-6, -1.0            # table rate scale error, c = -SF
    budgets = [(Contribution(f"mean @{t:g}", "data", EvalType.A, "normal", u, 1.0, u, math.inf),
                Contribution("table rate scale error", "station", EvalType.B, "rectangular",
                             common_u, common_c * v, abs(common_c * v) * common_u, math.inf))
               for t, u, v in zip(temps, own_u, values, strict=True)]
    piecewise = table_entry_uncertainty(temps, values, budgets, comp.piecewise_linear)
    for (t, unc), u, v in zip(piecewise, own_u, values, strict=True):
        assert unc.u == pytest.approx(math.hypot(u, common_u * v), rel=1e-9), t

    def poly(t, v):
        return comp.polynomial(t, v, degree=2)

    entries = table_entry_uncertainty(temps, values, budgets, poly)
    rng = np.random.default_rng(5)
    draws = 20000
    half = common_u * math.sqrt(3.0)
    common = rng.uniform(-half, half, draws)
    sampled = np.array(values) * (1 - common[:, None]) + rng.standard_normal((draws, 5)) * own_u
    fitted = np.array([np.polyval(np.polyfit(temps, row, 2), temps) for row in sampled])
    for i, (t, unc) in enumerate(entries):
        assert unc.u == pytest.approx(fitted[:, i].std(), rel=0.03), t
