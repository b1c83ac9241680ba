"""The one home of the noise-term Allan variances, checked against the definition itself.

Oracle independent of the closed forms: σ²(τ) = 2∫₀^∞ S(f)·sin⁴(πfτ)/(πfτ)² df
(IEEE Std 952 Annex C, one-sided PSD S), integrated numerically.
"""

import math

import numpy as np
import pytest
from scipy import integrate

from gyrocal.models import allan_theory as theory


def _avar_from_psd(psd, tau_s: float) -> float:
    def integrand(f):
        x = math.pi * f * tau_s
        return 2.0 * psd(f) * math.sin(x) ** 4 / x**2

    # split at the transfer function's zeros so quad sees smooth pieces
    edges = [0.0] + [k / tau_s for k in range(1, 400)]
    total = sum(integrate.quad(integrand, a, b, limit=200)[0] for a, b in zip(edges[:-1], edges[1:], strict=True))
    # beyond 400 lobes, sin⁴ averages to 3/8: a smooth tail quad integrates cleanly
    tail = integrate.quad(lambda f: 2.0 * psd(f) * 0.375 / (math.pi * f * tau_s) ** 2,
                          edges[-1], np.inf)[0]
    return total + tail


@pytest.mark.parametrize("tau_s", [0.3, 10.0, 300.0, 5000.0])
def test_markov_closed_form_equals_the_psd_integral(tau_s):
    sigma, tc = 0.7, 120.0
    psd = lambda f: 4.0 * sigma**2 * tc / (1.0 + (2.0 * math.pi * f * tc) ** 2)  # noqa: E731
    assert theory.markov_avar(tau_s, sigma, tc) == pytest.approx(_avar_from_psd(psd, tau_s),
                                                                 rel=2e-3)


def test_markov_small_tau_series_joins_the_closed_form():
    x = np.array([0.9e-3, 1.1e-3])
    values = theory.markov_avar(x, 1.0, 1.0)
    assert values[0] == pytest.approx(2 * x[0] / 3, rel=1e-3)
    assert values[1] == pytest.approx(2 * x[1] / 3, rel=1e-3)


def test_markov_peak_ratio_is_the_known_1_893():
    assert abs(theory.MARKOV_PEAK_TAU_PER_TC - 1.8926) < 2e-4


def test_white_rate_term_equals_the_psd_integral():
    n_deg_per_rth = 0.05
    h0 = 2.0 * (n_deg_per_rth * 60.0) ** 2  # one-sided (deg/h)²/Hz of white rate noise
    for tau_s in (1.0, 100.0):
        expected = _avar_from_psd(lambda f, h=h0: h, tau_s)
        ours = theory.noise_avar(tau_s, 0, n_deg_per_rth, 0, 0, 0)[0]
        assert ours == pytest.approx(expected, rel=2e-3)


def test_terms_add_and_flicker_floor():
    tau = np.array([1.0, 10.0])
    one = theory.noise_avar(tau, 0.5, 0.01, 0.03, 0.002, 0.001, markov=(0.2, 50.0))
    parts = (theory.term_avar_columns(tau) @ (np.array([0.5, 0.01, 0.03, 0.002, 0.001]) ** 2)
             + theory.markov_avar(tau, 0.2, 50.0))
    np.testing.assert_allclose(one, parts, rtol=1e-15)
    assert abs(theory.FLICKER_FLOOR_PER_B - 0.6643) < 1e-4


def test_the_noise_term_table_is_the_one_every_scheme_follows() -> None:
    """Model-file keys, fit keys and IEEE symbols come from models/noise_terms.py only."""
    from dataclasses import fields

    from gyrocal.analysis.allan.noise_fit import NoiseFit
    from gyrocal.metrology.metrics import METRICS
    from gyrocal.models.allan_theory import TERM_KEYS
    from gyrocal.models.gyro_model import NoiseParams
    from gyrocal.models.noise_terms import FIT_KEYS, MODEL_KEYS, NOISE_TERMS

    assert set(f.name for f in fields(NoiseParams)) == set(MODEL_KEYS)
    assert TERM_KEYS == FIT_KEYS == ("Q_arcsec", "N_deg_per_rth", "B_dph", "K_dph_per_rth",
                                     "R_dph_per_h")
    assert {f.name for f in fields(NoiseFit)} >= set(FIT_KEYS)
    assert all(f"allan.fit.{t.fit_key}" in METRICS for t in NOISE_TERMS)
    assert [t.symbol for t in NOISE_TERMS] == ["Q", "N", "B", "K", "R"]
