"""The coverage factor of a budget with a rectangular input, against closed forms.

For Σ c_i·X_i the 95 % point is known exactly in three cases, which the
convolution in ``metrology/gum.py`` must reproduce: one rectangular input
(P(|X| <= y) = y / a), two equal rectangular inputs (a triangular sum,
P(|Y| <= y) = 1 - (1 - y / 2a)²), and a rectangular plus a normal input
(the uniform mixture of normal CDFs, integrated in closed form); the
convolution's grid is good to about 5e-4 of k, ten times inside the ±0.5 %
of the Monte Carlo it replaced. A budget
with type A (Student t) inputs is checked against a large Monte Carlo draw.
"""

import math

import numpy as np
import pytest
from scipy import optimize, stats

from gyrocal.metrology.gum import Contribution, EvalType, linear_coverage_factor

P = 0.95


def part(u: float, distribution: str = "normal", dof: float = math.inf) -> Contribution:
    kind = EvalType.A if not math.isinf(dof) else EvalType.B
    return Contribution("x", "test", kind, distribution, u, 1.0, u, dof)


def k_of(parts: list[Contribution]) -> float:
    return linear_coverage_factor(parts, math.sqrt(sum(c.u_contribution ** 2 for c in parts)))


def test_one_rectangular_input_gives_p_times_root_3():
    assert k_of([part(2.5, "rectangular")]) == pytest.approx(P * math.sqrt(3.0), rel=1e-4)


def test_two_equal_rectangular_inputs_give_the_triangular_point():
    a = 1.0
    y = 2 * a * (1 - math.sqrt(1 - P))
    u_c = math.sqrt(2.0) * a / math.sqrt(3.0)
    parts = [part(a / math.sqrt(3.0), "rectangular")] * 2
    assert k_of(parts) == pytest.approx(y / u_c, rel=5e-4)


@pytest.mark.parametrize("sigma_over_a", [0.05, 0.3, 1.0, 3.0])
def test_rectangular_plus_normal_matches_the_closed_form(sigma_over_a):
    a, s = 1.0, sigma_over_a

    def g(z):
        return z * stats.norm.cdf(z) + stats.norm.pdf(z)

    def cdf(y):  # P(U + N <= y), U ~ U(-a, a), N ~ N(0, s²)
        return s / (2 * a) * (g((y + a) / s) - g((y - a) / s))

    y = optimize.brentq(lambda v: cdf(v) - cdf(-v) - P, 0.0, a + 10 * s, xtol=1e-12)
    u_c = math.hypot(a / math.sqrt(3.0), s)
    parts = [part(a / math.sqrt(3.0), "rectangular"), part(s)]
    assert k_of(parts) == pytest.approx(y / u_c, rel=5e-4)


@pytest.mark.parametrize("dof", [1.0, 3.0, 12.0])
def test_type_a_inputs_are_scaled_t_as_in_a_large_monte_carlo_draw(dof):
    parts = [part(1.0, "rectangular"), part(0.6, dof=dof), part(0.4)]
    rng = np.random.default_rng(101)
    n = 2_000_000
    total = (rng.uniform(-math.sqrt(3.0), math.sqrt(3.0), n) + 0.6 * rng.standard_t(dof, n)
             + 0.4 * rng.standard_normal(n))
    u_c = math.sqrt(1.0 + 0.36 + 0.16)
    # 2e6 draws: the 95 % point to about ±0.2 %
    assert k_of(parts) == pytest.approx(float(np.quantile(np.abs(total), P)) / u_c, rel=4e-3)


@pytest.mark.parametrize("dof_main", [1.0, 3.0, 9.0])
def test_a_long_budget_on_the_short_window_equals_the_full_convolution(monkeypatch, dof_main):
    """121 type A terms and a rectangular (a compensation table's budget, reports/sections/uncertainty.py):
    the convolution kept over four reaches gives the k of the full n-reach one. A dominant
    low-dof term puts the most mass in the folded end cells, the case the window could miss."""
    import gyrocal.metrology.gum as gum

    rng = np.random.default_rng(30)
    parts = [part(float(u), dof=9.0) for u in rng.uniform(0.01, 0.1, 120)]
    parts += [part(1.0, dof=dof_main), part(0.3, "rectangular")]
    u_c = math.sqrt(sum(c.u_contribution ** 2 for c in parts))
    short = linear_coverage_factor(parts, u_c)
    monkeypatch.setattr(gum, "COVERAGE_WINDOW_REACHES", len(parts))
    full = linear_coverage_factor(parts, u_c)
    assert short == pytest.approx(full, rel=1e-9, abs=0.0)
