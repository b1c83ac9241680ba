"""Joint weighted least-squares fit of the IEEE 952 noise terms to an Allan curve.

Reading slopes off a log-log plot (the Chikovani/IEEE Annex C recipe) is
biased whenever terms overlap: the minimum of the curve sits above the
bias-instability floor when angle random walk and rate random walk meet
there, so B read at the minimum comes out high. Here all terms are fitted
together in the variance domain, where they add:

    σ²(τ) = 3Q²/τ² + 3600·N²/τ + (2 ln2/π)·B² + K²·τ/10800 + R²·τ²/(2·3600²)
            [+ σ_M²·g(τ/T)]

with σ in deg/h, τ in s, Q in arcsec, N in deg/√h, K in deg/h/√h, R in
deg/h/h. The unknowns (squared coefficients) are non-negative, so the fit is
NNLS on weighted columns. Weights: var(σ̂²) ≈ 2σ⁴/edf; σ⁴ is the *model*
value, iterated (IRLS) — weighting by the measured σ̂ would favour points
that happen to fall low and bias every term low.

Markov (first-order Gauss–Markov, steady-state std σ_M, correlation time T)
uses its exact Allan variance
    σ²(τ) = (2σ_M²T/τ)·[1 − (T/2τ)(3 − 4e^{−τ/T} + e^{−2τ/T})],
which peaks at τ ≈ 1.89·T. T is found by a 1-D search (log grid, then a
bounded refinement) with the linear terms re-solved at each T.

Uncertainties: neighbouring points of a dense log-spaced curve share most of
their data, so their errors are strongly correlated; a WLS that treated 100
points as independent would overstate the information several times. The
point estimate stays a diagonal-weight WLS (robust: a GLS with a nearly
singular modelled covariance amplifies every small model mismatch), but its
covariance is the sandwich (AᵀWA)⁻¹AᵀW C W A(AᵀWA)⁻¹ with a correlation
model between points, ρ(τ_i, τ_j) = 1 / (1 + c·ln²(τ_j/τ_i)), c depending on
the local noise type (white rate 1.64, flicker rate 0.89, rate random walk
0.26; c_ij the mean of the two points'), matched to the correlation of
overlapping AVAR estimates measured on simulated power-law noise (1 octave
apart: 0.56 / 0.70 / 0.89). The covariance is scaled by the Birge ratio
χ²/E[χ²] when the model fits worse than the weights say, where
E[χ²] = n − trace(Hρ) (H the weighted hat matrix) holds for correlated points.

Markov inclusion rule ("auto"): include it when either its χ² drop, divided by its
expected value per parameter under "no Markov" (trace((H₁−H₀)ρ)/2, at least
1, so the point correlation does not fake significance), exceeds 5 × the
99.9 % quantile of χ²(2) times the Birge ratio (the factor 5 is empirical,
see _MARKOV_THRESHOLD_FACTOR), or the fit without it does not fit and the term
cures that (see _MARKOV_MISFIT_BIRGE); and when its peak 1.89·T lies at least a factor
8 inside both ends of the measured τ range (otherwise a Markov term only
mimics N, or K plus the scatter of the last few low-EDF points — on
simulated N + K data it was wrongly added in 5 of 12 seeds without this
margin); and when σ_M > 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from gyrocal.models.allan_theory import (
    MARKOV_PEAK_TAU_PER_TC,
    TERM_KEYS,
    markov_avar,
    term_avar_columns,
)

TERM_NAMES = TERM_KEYS
MARKOV_PEAK_RATIO = MARKOV_PEAK_TAU_PER_TC  # τ_peak / T for a first-order Gauss–Markov process
_MARKOV_SIGNIFICANCE = 0.999
_IRLS_ROUNDS = 4
# The hump must be seen on both sides: a peak within the last factor of 8 of the curve
# is indistinguishable from rate random walk plus a scatter of the few long-τ points.
_HUMP_MARGIN = 8.0
# The WLS χ² of correlated, non-Gaussian AVAR points spreads far wider than χ²(2):
# on simulated N+K and N+B+K curves a spurious Markov term lowered χ² by up to 46
# (24 runs), a real hump (σ = 0.5 deg/h, T = 40 s) by ~10⁴. Threshold: 5 × 13.8 = 69.
_MARKOV_THRESHOLD_FACTOR = 5.0
#: Second, independent way a hump qualifies: the curve without a Markov term does not fit
#: (χ² over its correlated-point expectation above 1.5) and the Markov term cuts that
#: ratio by more than 3×. Measured on simulated records: VG951D (48 h, with its hump)
#: 1.75–4.4 → 0.25–0.58 (cut 6.4–7.6×); no hump (VG951D without it, KVG25, nominal FOG,
#: 12 records) 0.48–1.13 with cuts 0.77–1.41×. The χ² rule above alone missed the
#: VG951D hump in 4 of 5 seeds, because the per-parameter normalisation of the drop
#: (correlated points) is very conservative for a hump spanning a decade.
_MARKOV_MISFIT_BIRGE = 1.5
#: Beyond this 1-σ error of ln T (a factor of 10¹²) the correlation time is unconstrained:
#: its interval is reported as (0, ∞) instead of overflowing exp() (seen on quantized data).
_MARKOV_TIME_UNCONSTRAINED = math.log(1e12)
_MARKOV_BIRGE_DROP = 3.0


#: One-sided 95 % normal quantile: the bound a term that cannot be identified is judged by.
UPPER_BOUND_Z = 1.6449


@dataclass(frozen=True)
class TermEstimate:
    """One noise coefficient with its 1-σ standard error and 68 % interval.

    The interval is built on the squared coefficient (what the fit is linear
    in), clipped at zero, then square-rooted, so a term fitted at zero still
    gets an honest upper bound.
    """

    value: float
    stderr: float
    lo: float
    hi: float

    @property
    def identifiable(self) -> bool:
        """The record tells this term from zero: fitted above zero with a 68 % interval clear of it.

        A term held at zero by the fit (FOG quantization, rate ramp on a short
        record) is not "0": the data say only that it is below an upper bound.
        """
        return self.value > 0.0 and self.lo > 0.0 and math.isfinite(self.stderr)

    def upper_bound(self, z: float = UPPER_BOUND_Z) -> float:
        """One-sided upper bound of the term (default 95 %), on the squared coefficient as the fit."""
        if not math.isfinite(self.stderr):
            return math.inf
        coeff = self.value ** 2
        sd_c = 2.0 * self.value * self.stderr if self.value > 0 else self.stderr ** 2
        return math.sqrt(max(coeff + z * sd_c, 0.0))



@dataclass(frozen=True)
class MarkovEstimate:
    """First-order Gauss–Markov term: steady-state std (deg/h) and correlation time (s)."""

    sigma_dph: TermEstimate
    tau_s: TermEstimate
    tau_peak_s: float
    delta_chi2: float


@dataclass(frozen=True)
class NoiseFit:
    """Fitted IEEE 952 coefficients, each with uncertainty; see the module docstring."""

    Q_arcsec: TermEstimate
    N_deg_per_rth: TermEstimate
    B_dph: TermEstimate
    K_dph_per_rth: TermEstimate
    R_dph_per_h: TermEstimate
    markov: MarkovEstimate | None
    chi2: float
    dof: int

    def model_adev(self, tau_s) -> np.ndarray:
        """Fitted Allan deviation (deg/h) at ``tau_s``."""
        tau = np.asarray(tau_s, dtype=float)
        coeffs = np.array([getattr(self, name).value ** 2 for name in TERM_NAMES])
        variance = _design(tau) @ coeffs
        if self.markov is not None:
            variance = variance + self.markov.sigma_dph.value ** 2 * markov_avar_unit(
                tau, self.markov.tau_s.value)
        return np.sqrt(variance)

    def to_json(self) -> dict:
        """The `fit` object of results.json / `analyze allan --json` (values only)."""
        out = {name: getattr(self, name).value for name in TERM_NAMES}
        out["markov"] = None if self.markov is None else {
            "sigma_dph": self.markov.sigma_dph.value, "tau_s": self.markov.tau_s.value}
        return out


def markov_avar_unit(tau_s, correlation_time_s: float) -> np.ndarray:
    """Allan variance of a unit-variance first-order Gauss–Markov process."""
    return markov_avar(tau_s, 1.0, correlation_time_s)


def _design(tau_s: np.ndarray) -> np.ndarray:
    """Columns: AVAR per unit squared coefficient, in the order of TERM_NAMES."""
    return term_avar_columns(tau_s)


@dataclass
class _Solution:
    coeffs: np.ndarray
    chi2: float
    model: np.ndarray


# Correlation width c per noise type α (see module docstring).
_CORRELATION_C = {2: 1.64, 1: 1.64, 0: 1.64, -1: 0.89, -2: 0.26}


def correlation_matrix(tau_s: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Modelled correlation between the AVAR estimates at the points of one curve."""
    c = np.array([_CORRELATION_C[int(np.clip(a, -2, 2))] for a in alpha])
    c_pair = 0.5 * (c[:, None] + c[None, :])
    log_ratio = np.log(tau_s)[:, None] - np.log(tau_s)[None, :]
    rho = 1.0 / (1.0 + c_pair * log_ratio**2)
    # Mixed widths need not give a positive-definite matrix: clip its spectrum.
    values, vectors = np.linalg.eigh(rho)
    values = np.maximum(values, 1e-6)
    rho = (vectors * values) @ vectors.T
    d = np.sqrt(np.diag(rho))
    return rho / np.outer(d, d)


def _alpha_from_slope(tau_s: np.ndarray, avar: np.ndarray) -> np.ndarray:
    """Noise type from the local log-log slope μ of the AVAR: α = −μ − 1."""
    slope = np.gradient(np.log(avar), np.log(tau_s))
    return np.clip(np.round(-slope - 1.0), -2, 2).astype(int)


def _sd(model: np.ndarray, edf: np.ndarray) -> np.ndarray:
    """sd(σ̂²) = σ²·√(2/edf), floored so a zero model cannot give infinite weight."""
    return np.maximum(model, np.max(model) * 1e-12) * np.sqrt(2.0 / edf)


def _wls_nnls(design: np.ndarray, avar: np.ndarray, edf: np.ndarray) -> _Solution:
    """Non-negative WLS, weights re-evaluated at the model (IRLS)."""
    sd = _sd(avar, edf)
    coeffs = np.zeros(design.shape[1])
    model = avar
    for _ in range(_IRLS_ROUNDS):
        weighted = design / sd[:, None]
        scale = np.linalg.norm(weighted, axis=0)
        scale[scale == 0.0] = 1.0
        solution, _ = optimize.nnls(weighted / scale, avar / sd)
        coeffs = solution / scale
        model = design @ coeffs
        sd = _sd(model, edf)
    chi2 = float(np.sum(((avar - model) / sd) ** 2))
    return _Solution(coeffs, chi2, model)


def _active_weighted(design: np.ndarray, solution: _Solution, edf: np.ndarray):
    """Weighted design restricted to the columns not held at zero by the bound."""
    weighted = design / _sd(solution.model, edf)[:, None]
    active = solution.coeffs > 0
    return weighted, active


def _hat_trace_rho(design: np.ndarray, solution: _Solution, edf: np.ndarray,
                   rho: np.ndarray) -> float:
    """trace(Hρ) for the active columns: the χ² the fitted parameters absorb."""
    weighted, active = _active_weighted(design, solution, edf)
    a = weighted[:, active]
    if a.shape[1] == 0:
        return 0.0
    hat = a @ np.linalg.pinv(a.T @ a) @ a.T
    return float(np.trace(hat @ rho))


def _sandwich_covariance(design: np.ndarray, solution: _Solution, edf: np.ndarray,
                         rho: np.ndarray, birge: float) -> np.ndarray:
    """Covariance of the WLS coefficients when the point errors are correlated (ρ).

    Columns held at zero by the bound get the variance they would have if
    freed (their upper bound is then honest rather than zero).
    """
    weighted, _ = _active_weighted(design, solution, edf)
    scale = np.linalg.norm(weighted, axis=0)
    scale[scale == 0.0] = 1.0
    a = weighted / scale
    bread = np.linalg.pinv(a.T @ a)
    cov_scaled = bread @ (a.T @ rho @ a) @ bread
    return cov_scaled / np.outer(scale, scale) * birge


def _estimate(coeff: float, variance: float, z: float = 1.0) -> TermEstimate:
    """Value, stderr and interval of √c from c and var(c)."""
    sd_c = math.sqrt(max(variance, 0.0))
    value = math.sqrt(max(coeff, 0.0))
    stderr = sd_c / (2.0 * value) if value > 0 else math.sqrt(sd_c)
    lo = math.sqrt(max(coeff - z * sd_c, 0.0))
    hi = math.sqrt(max(coeff + z * sd_c, 0.0))
    return TermEstimate(value, stderr, lo, hi)


def _markov_search(tau_s, avar, edf, rho, base_design) -> tuple[float, _Solution]:
    """Best correlation time T with the linear terms re-solved at each trial T."""
    t_low = tau_s[0] / MARKOV_PEAK_RATIO
    t_high = tau_s[-1] / MARKOV_PEAK_RATIO

    def chi2_at(log_t: float) -> float:
        column = markov_avar_unit(tau_s, math.exp(log_t))[:, None]
        return _wls_nnls(np.hstack([base_design, column]), avar, edf).chi2

    grid = np.linspace(math.log(t_low), math.log(t_high), 40)
    values = [chi2_at(g) for g in grid]
    best = int(np.argmin(values))
    lo = grid[max(best - 1, 0)]
    hi = grid[min(best + 1, grid.size - 1)]
    refined = optimize.minimize_scalar(chi2_at, bounds=(lo, hi), method="bounded",
                                       options={"xatol": 1e-3})
    log_t = float(refined.x) if refined.fun <= values[best] else float(grid[best])
    t_best = math.exp(log_t)
    column = markov_avar_unit(tau_s, t_best)[:, None]
    return t_best, _wls_nnls(np.hstack([base_design, column]), avar, edf)


def _validated(tau_s, adev_dph, edf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tau = np.asarray(tau_s, dtype=float)
    adev = np.asarray(adev_dph, dtype=float)
    if tau.ndim != 1 or tau.shape != adev.shape:
        raise ValueError(f"tau_s and adev_dph must be 1-D of equal length, got {tau.shape} "
                         f"and {adev.shape}")
    if tau.size < 6:
        raise ValueError(f"{tau.size} Allan points are too few to fit the noise terms")
    if not (np.all(np.isfinite(tau)) and np.all(tau > 0) and np.all(np.diff(tau) > 0)):
        raise ValueError("tau_s must be finite, positive and strictly increasing")
    if not (np.all(np.isfinite(adev)) and np.all(adev > 0)):
        bad = int(np.flatnonzero(~(np.isfinite(adev) & (adev > 0)))[0])
        raise ValueError(f"adev_dph[{bad}] = {adev[bad]} is not a positive finite deviation")
    if edf is None:
        # Without EDFs: the white-rate approximation edf ≈ N_terms/m is unknown here,
        # so weight every point by its relative scatter alone (constant edf).
        edf_arr = np.full(tau.shape, 10.0)
    else:
        edf_arr = np.asarray(edf, dtype=float)
        if edf_arr.shape != tau.shape or not np.all(edf_arr > 0):
            raise ValueError("edf must be positive and have the same length as tau_s")
    return tau, adev, edf_arr


def fit_noise_terms(tau_s, adev_dph, edf=None, markov: str | bool = "auto",
                    alpha=None) -> NoiseFit:
    """Fit Q, N, B, K, R (and optionally a Markov term) jointly to an Allan curve.

    ``edf`` are the equivalent degrees of freedom per point and ``alpha`` the
    noise type per point (both from
    :func:`gyrocal.analysis.allan.deviation.overlapping_adev`); without ``edf`` all
    points get equal relative weight, without ``alpha`` the type comes from
    the local slope of the curve. ``markov`` is "auto" (include when
    significant, see module docstring), True (always) or False (never).
    """
    if markov not in ("auto", True, False):
        raise ValueError(f"markov must be 'auto', True or False, got {markov!r}")
    tau, adev, edf_arr = _validated(tau_s, adev_dph, edf)
    avar = adev**2
    alpha_arr = _alpha_from_slope(tau, avar) if alpha is None else np.asarray(alpha, dtype=int)
    if alpha_arr.shape != tau.shape:
        raise ValueError("alpha must have the same length as tau_s")
    rho = correlation_matrix(tau, alpha_arr)
    design = _design(tau)

    plain = _wls_nnls(design, avar, edf_arr)
    chosen, chosen_design, t_markov = plain, design, None
    delta_chi2 = 0.0
    if markov is not False:
        t_best, with_markov = _markov_search(tau, avar, edf_arr, rho, design)
        markov_design = np.hstack([design, markov_avar_unit(tau, t_best)[:, None]])
        delta_chi2 = plain.chi2 - with_markov.chi2
        significant = _markov_significant(tau, design, plain, markov_design, with_markov,
                                          edf_arr, rho, t_best)
        if markov is True or significant:
            chosen, chosen_design, t_markov = with_markov, markov_design, t_best

    n_params = chosen_design.shape[1] + (1 if t_markov is not None else 0)
    dof = max(tau.size - n_params, 1)
    expected_chi2 = max(tau.size - _hat_trace_rho(chosen_design, chosen, edf_arr, rho), 1.0)
    birge = max(chosen.chi2 / expected_chi2, 1.0)
    cov = _sandwich_covariance(chosen_design, chosen, edf_arr, rho, birge)

    terms = {name: _estimate(chosen.coeffs[i], cov[i, i]) for i, name in enumerate(TERM_NAMES)}
    markov_estimate = None
    if t_markov is not None:
        markov_estimate = _markov_estimate(tau, avar, edf_arr, rho, design, chosen, cov,
                                           t_markov, birge, delta_chi2)
    return NoiseFit(**terms, markov=markov_estimate, chi2=chosen.chi2, dof=dof)


def _markov_significant(tau, design, plain, markov_design, with_markov, edf, rho,
                        t_best: float) -> bool:
    """Whether the Markov term earns its place (module docstring): its χ² drop per absorbed
    parameter, or a misfit it cures, with its hump inside the curve and a positive size."""
    delta_chi2 = plain.chi2 - with_markov.chi2
    absorbed_plain = _hat_trace_rho(design, plain, edf, rho)
    absorbed_markov = _hat_trace_rho(markov_design, with_markov, edf, rho)
    per_parameter = max((absorbed_markov - absorbed_plain) / 2.0, 1.0)
    birge_markov = max(with_markov.chi2 / max(tau.size - absorbed_markov, 1.0), 1.0)
    peak = MARKOV_PEAK_RATIO * t_best
    birge_plain = plain.chi2 / max(tau.size - absorbed_plain, 1.0)
    by_chi2_drop = (delta_chi2 / per_parameter
                    > _MARKOV_THRESHOLD_FACTOR * stats.chi2.ppf(_MARKOV_SIGNIFICANCE, 2)
                    * birge_markov)
    by_misfit = (birge_plain > _MARKOV_MISFIT_BIRGE
                 and birge_plain > _MARKOV_BIRGE_DROP * max(birge_markov, 1e-12))
    return bool(
        (by_chi2_drop or by_misfit)
        and _HUMP_MARGIN * tau[0] < peak < tau[-1] / _HUMP_MARGIN
        and with_markov.coeffs[-1] > 0
    )


def _markov_estimate(tau, avar, edf, rho, design, chosen, cov, t_markov: float, birge: float,
                     delta_chi2: float) -> MarkovEstimate:
    """The Markov term's size and correlation time with their uncertainties."""
    sigma = _estimate(chosen.coeffs[-1], cov[-1, -1])
    t_err = _markov_time_error(tau, avar, edf, rho, design, t_markov, birge)
    if t_err > _MARKOV_TIME_UNCONSTRAINED:  # a flat χ²(ln T): say so, never overflow
        tau_estimate = TermEstimate(t_markov, math.inf, 0.0, math.inf)
    else:
        tau_estimate = TermEstimate(t_markov, t_markov * t_err, t_markov * math.exp(-t_err),
                                    t_markov * math.exp(t_err))
    return MarkovEstimate(
        sigma_dph=sigma,
        tau_s=tau_estimate,
        tau_peak_s=MARKOV_PEAK_RATIO * t_markov,
        delta_chi2=delta_chi2,
    )


def _markov_time_error(tau, avar, edf, rho, design, t_markov: float, birge: float) -> float:
    """1-σ error of ln T from the curvature of χ²(ln T) (Δχ² = Birge ratio)."""
    def chi2_at(log_t: float) -> float:
        column = markov_avar_unit(tau, math.exp(log_t))[:, None]
        return _wls_nnls(np.hstack([design, column]), avar, edf).chi2

    step = 0.05
    centre = math.log(t_markov)
    c0, cm, cp = chi2_at(centre), chi2_at(centre - step), chi2_at(centre + step)
    curvature = (cp - 2.0 * c0 + cm) / step**2
    if curvature <= 0:
        return float("inf")
    return math.sqrt(2.0 * birge / curvature)
