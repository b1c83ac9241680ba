"""The Allan variance of the IEEE Std 952 noise terms and of a Gauss–Markov process: one home.

The simulator (which must produce a given Allan curve), the noise fit (which
reads the terms back from a measured curve) and the discrepancy workflow
(which compares a model's curve with the data) all need the same theory; a
second copy of a formula is a second chance for the two sides to disagree
unnoticed (they did: two Markov formulas and two peak ratios, 1.89 and 1.8926).

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²τ/3 + R²τ²/2   (+ Markov terms)

in the units of gyro-model.md: Q arcsec, N deg/√h, B deg/h, K deg/h/√h,
R deg/h/h, τ s, σ deg/h (hence the 3600 factors below).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from gyrocal.models.noise_terms import FIT_KEYS

#: The five noise coefficients, in the order of :func:`term_avar_columns`
#: (the results.json / `analyze allan` fit keys of interfaces.md; models/noise_terms.py).
TERM_KEYS = FIT_KEYS

#: Allan variance of flicker (bias-instability) noise per B²: 2 ln2 / π.
B_AVAR_PER_B2 = 2.0 * math.log(2.0) / math.pi
#: Allan floor of flicker noise in units of B: √(2 ln2 / π) ≈ 0.6643.
FLICKER_FLOOR_PER_B = math.sqrt(B_AVAR_PER_B2)


def markov_avar(tau_s, sigma_dph: float, tc_s: float) -> np.ndarray:
    """Allan variance (deg/h)² of a first-order Gauss–Markov process (std σ, correlation T).

    σ²(τ) = (2σ²T/τ)·[1 − (T/2τ)(3 − 4e^{−τ/T} + e^{−2τ/T})] (IEEE 952 Annex C,
    with q_c²·T/2 = σ²). For τ ≪ T the bracket cancels badly in floating
    point, so its series x/3 − x²/4 (x = τ/T) is used below x = 1e-3.
    """
    x = np.asarray(tau_s, dtype=float) / float(tc_s)
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    bracket = 1.0 - (3.0 - 4.0 * np.exp(-xs) + np.exp(-2.0 * xs)) / (2.0 * xs)
    bracket = np.where(small, x**2 / 3.0 - x**3 / 4.0, bracket)
    return 2.0 * sigma_dph**2 * bracket / np.where(small, np.maximum(x, 1e-300), xs)


def _markov_peak_ratio() -> float:
    """τ at the Allan-deviation peak of a Gauss–Markov process, per correlation time."""
    found = optimize.minimize_scalar(lambda x: -float(markov_avar(x, 1.0, 1.0)),
                                     bounds=(0.5, 10.0), method="bounded",
                                     options={"xatol": 1e-9})
    return float(found.x)


#: τ_peak / T_c of a Gauss–Markov hump (≈ 1.8926; Chikovani's T_c = τ_peak/1.89).
MARKOV_PEAK_TAU_PER_TC = _markov_peak_ratio()


def term_avar_columns(tau_s) -> np.ndarray:
    """Allan variance per unit squared coefficient, one column per term of :data:`TERM_KEYS`."""
    tau = np.asarray(tau_s, dtype=float)
    return np.column_stack([
        3.0 / tau**2,                   # Q: 3Q²/τ², Q in arcsec → (deg/h)² with τ in s
        3600.0 / tau,                   # N: N²/τ with N in deg/√h
        np.full_like(tau, B_AVAR_PER_B2),
        tau / 10800.0,                  # K: K²τ/3 with K in deg/h/√h
        tau**2 / (2.0 * 3600.0**2),     # R: R²τ²/2 with R in deg/h/h
    ])


def noise_avar(tau_s, q_arcsec: float, n_deg_per_rth: float, b_dph: float,
               k_dph_per_rth: float, r_dph_per_h: float,
               markov: tuple[float, float] | None = None) -> np.ndarray:
    """Allan variance (deg/h)² of the five terms plus an optional (σ deg/h, T s) Markov term."""
    coeffs = np.array([q_arcsec, n_deg_per_rth, b_dph, k_dph_per_rth, r_dph_per_h]) ** 2
    avar = term_avar_columns(tau_s) @ coeffs
    if markov is not None:
        avar = avar + markov_avar(tau_s, markov[0], markov[1])
    return avar
