"""GUM (JCGM 100) propagation: budget, Welch–Satterthwaite dof, coverage factor.

One engine for every calibrated quantity, so that each reported number's
uncertainty is built the same auditable way: a measurement function
``f(x_1..x_N)`` of inputs with standard uncertainties ``u(x_i)`` (type A with
their degrees of freedom, type B with ν = ∞ unless declared), sensitivity
coefficients ``c_i = ∂f/∂x_i`` taken numerically by central differences (GUM
5.1.3, note 2: the function is the analysis code itself, not a hand-derived
formula that could drift from it), the combined ``u_c² = Σ (c_i u_i)²``
(uncorrelated inputs, GUM 5.1.2), the effective degrees of freedom by
Welch–Satterthwaite (GUM G.4.1) and ``k = t_{95 %}(ν_eff)`` (GUM G.3).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np
from scipy import fft as scipy_fft
from scipy import special, stats

COVERAGE_PROBABILITY = 0.95


class EvalType(str, Enum):
    """GUM 4.2 (statistics of the data) or 4.3 (other knowledge: certificates, specs)."""

    A = "A"
    B = "B"


@dataclass(frozen=True)
class Input:
    """One input quantity of a measurement function with its standard uncertainty."""

    name: str
    value: float
    u: float
    kind: EvalType
    source: str
    dof: float = math.inf
    distribution: str = "normal"


@dataclass(frozen=True)
class Contribution:
    """One budget line: u(x_i), c_i, |c_i|·u(x_i) and ν_i."""

    name: str
    source: str
    kind: EvalType
    distribution: str
    u_input: float
    sensitivity: float
    u_contribution: float
    dof: float

    def to_json(self) -> dict:
        return {"name": self.name, "source": self.source, "type": self.kind.value,
                "distribution": self.distribution, "u_input": self.u_input,
                "sensitivity": self.sensitivity, "u_contribution": self.u_contribution,
                "dof": None if math.isinf(self.dof) else self.dof}


@dataclass(frozen=True)
class Uncertainty:
    """A measured value with combined u, ν_eff, k and U = k·u (≈ 95 % coverage)."""

    value: float
    u: float
    dof_eff: float
    k: float
    budget: tuple[Contribution, ...]

    @property
    def U(self) -> float:  # noqa: N802 - the GUM's symbol for the expanded uncertainty
        return self.k * self.u

    def to_json(self) -> dict:
        """The ``u``, ``U``, ``k``, ``dof_eff`` and ``budget`` keys results.json carries."""
        return {"u": self.u, "U": self.U, "k": self.k,
                "dof_eff": None if math.isinf(self.dof_eff) else self.dof_eff,
                "coverage_probability": COVERAGE_PROBABILITY,
                "budget": [c.to_json() for c in self.budget]}


def rectangular(half_width: float) -> float:
    """Standard uncertainty of a rectangular (uniform) distribution ±a: a/√3 (GUM 4.3.7)."""
    return abs(half_width) / math.sqrt(3.0)


def welch_satterthwaite(contributions: Sequence[float], dofs: Sequence[float]) -> float:
    """ν_eff = u_c⁴ / Σ u_i⁴/ν_i (GUM G.4.1); ∞ when every ν_i is infinite."""
    u_c2 = sum(c * c for c in contributions)
    denominator = sum(c ** 4 / nu for c, nu in zip(contributions, dofs, strict=True)
                      if not math.isinf(nu) and c != 0.0)
    if u_c2 == 0.0 or denominator == 0.0:
        return math.inf
    return u_c2 ** 2 / denominator


def coverage_factor(dof_eff: float, p: float = COVERAGE_PROBABILITY) -> float:
    """k = t_p(ν_eff) (GUM G.3.4); the normal quantile when ν_eff is infinite."""
    if math.isinf(dof_eff) or dof_eff > 1e7:
        return float(stats.norm.ppf(0.5 + p / 2.0))
    return float(stats.t.ppf(0.5 + p / 2.0, max(dof_eff, 1.0)))


#: Grid of the coverage factor's convolution: cells per u_c, and how far out (in u_c beyond
#: the rectangular half-widths) each distribution is kept before its tails are folded in.
COVERAGE_CELLS_PER_U = 40
COVERAGE_REACH_U = 40.0
#: The convolution is kept over ±this many times the reach (and the FFT is that long): the
#: sum of n contributions spans n reaches, but beyond four the mass is below ~1e-8 (it needs
#: four tails folded to the grid's end at once), and the cyclic FFT keeps it in the total.
#: Up to four contributions nothing changes; a report's 121-term budgets got 30× shorter FFTs.
COVERAGE_WINDOW_REACHES = 4


def combine(value: float, contributions: Sequence[Contribution]) -> Uncertainty:
    """Combined standard uncertainty of uncorrelated contributions, with ν_eff and k.

    k is t_95(ν_eff) (GUM G.3) when every input is normal or a type A mean. When a
    rectangular input is among them the output is not near-normal - a table-rate accuracy
    of ±10 ppm dominates a scale factor's budget, and t(∞) = 1.96 then over-covers (the
    measured coverage was 100 % where 95 % was claimed). There k is the 95 % point of the
    linearised model Y = Σ c_i·X_i sampled by JCGM 101 (each X_i from its own distribution,
    type A ones as scaled t with their ν_i), divided by u_c.
    """
    parts = [c.u_contribution for c in contributions]
    u = math.sqrt(sum(p * p for p in parts))
    dof = welch_satterthwaite(parts, [c.dof for c in contributions])
    k = coverage_factor(dof)
    if u > 0.0 and any(c.distribution == "rectangular" and c.u_contribution > 0.0
                       for c in contributions):
        k = linear_coverage_factor(contributions, u)
    return Uncertainty(float(value), u, dof, k, tuple(contributions))


def linear_coverage_factor(contributions: Sequence[Contribution], u_c: float,
                           p: float = COVERAGE_PROBABILITY) -> float:
    """k such that ±k·u_c holds ``p`` of Σ c_i·X_i (JCGM 101, applied to the linearised model).

    The distribution of the sum is computed, not sampled: each X_i (rectangular,
    normal, or for a type A mean t_ν scaled by its u, JCGM 101 6.4.9.2) is put on
    a common grid as exact cell probabilities (differences of its CDF; the tails
    beyond the grid folded into its end cells) and the cells are convolved by
    FFT. Putting every X_i on the cell centres adds about n·h²/12 of variance
    (h = u_c/40) and the mass is spread linearly within a cell: k to about 5e-4
    (closed forms in tests/reports/test_gum_coverage.py), inside the ±0.5 % of
    the 100,000 Monte Carlo draws it replaces (~10 ms a call; this ~0.3 ms),
    and the same on every machine and in ``verify``, with no seed.
    """
    parts = [c for c in contributions if c.u_contribution > 0.0]
    if not parts or u_c <= 0.0:
        return coverage_factor(math.inf, p)
    h = u_c / COVERAGE_CELLS_PER_U
    reach = sum(c.u_contribution * math.sqrt(3.0) for c in parts
                if c.distribution == "rectangular") + COVERAGE_REACH_U * u_c
    half_cells = int(math.ceil(reach / h))
    inner = (np.arange(-half_cells, half_cells + 1) + 0.5) * h      # upper edges but the last
    window = min(len(parts), COVERAGE_WINDOW_REACHES) * half_cells   # cells each side kept
    size = 2 * window + 1
    n_fft = int(scipy_fft.next_fast_len(size, real=True))
    spectrum = np.ones(n_fft // 2 + 1, dtype=complex)
    for c in parts:
        upper = _cdf(c, inner[half_cells:-1])          # x > 0; the distributions are symmetric
        cdf = np.concatenate(([0.0], 1.0 - upper[::-1], upper, [1.0]))
        spectrum *= scipy_fft.rfft(np.diff(cdf), n_fft)
    # the sum's centre is cell len(parts)·half_cells of the linear convolution; the cyclic one
    # holds cell j at j mod n_fft
    cells = (len(parts) * half_cells - window + np.arange(size)) % n_fft
    mass = np.clip(scipy_fft.irfft(spectrum, n_fft)[cells], 0.0, None)
    centre = size // 2
    folded = mass[centre:].copy()
    folded[1:] += mass[:centre][::-1]
    cumulative = np.cumsum(folded) / mass.sum()
    i = int(np.searchsorted(cumulative, p))
    below = cumulative[i - 1] if i > 0 else 0.0
    # cell i spans |y| in [(i - 1/2) h, (i + 1/2) h] (cell 0: [0, h/2]); linear within it
    lower = max(i - 0.5, 0.0) * h
    width = (i + 0.5) * h - lower
    y = lower + width * (p - below) / max(cumulative[i] - below, 1e-300)
    return float(y / u_c)


def _cdf(c: Contribution, x: np.ndarray) -> np.ndarray:
    """CDF of the contribution c_i·X_i at ``x`` (the linearised model's own distributions)."""
    u = c.u_contribution
    if c.distribution == "rectangular":
        half = u * math.sqrt(3.0)
        return np.clip((x + half) / (2.0 * half), 0.0, 1.0)
    if c.kind is EvalType.A and not math.isinf(c.dof):
        return special.stdtr(max(c.dof, 1.0), x / u)
    return special.ndtr(x / u)


def propagate(func: Callable[[dict[str, float]], float], inputs: Sequence[Input],
              relative_step: float = 1e-2) -> Uncertainty:
    """GUM law of propagation with numerical sensitivity coefficients.

    ``func`` takes {name: value} and returns the measurand. The step for each
    input is ``relative_step·u(x_i)`` (small against u, so the linearisation
    is the GUM's first-order one over the region the input plausibly spans).
    """
    point = {i.name: i.value for i in inputs}
    if len(point) != len(inputs):
        raise ValueError("input names must be unique")
    value = float(func(point))
    contributions = []
    for item in inputs:
        if item.u == 0.0:
            sensitivity = 0.0
        else:
            h = relative_step * item.u
            up = float(func(point | {item.name: item.value + h}))
            down = float(func(point | {item.name: item.value - h}))
            sensitivity = (up - down) / (2.0 * h)
        contributions.append(Contribution(item.name, item.source, item.kind, item.distribution,
                                          item.u, sensitivity, abs(sensitivity) * item.u,
                                          item.dof))
    return combine(value, contributions)


def monte_carlo(func: Callable[[dict[str, float]], float], inputs: Sequence[Input],
                draws: int = 20000, seed: int = 0) -> tuple[float, float, float, float]:
    """JCGM 101 (GUM Supplement 1): (mean, std, 2.5 %, 97.5 % quantiles) of f by sampling.

    Type A inputs with finite ν are drawn from scaled-shifted t distributions
    (JCGM 101 6.4.9), rectangular ones uniformly, the rest normally.
    """
    rng = np.random.default_rng(seed)
    samples = {}
    for item in inputs:
        if item.distribution == "rectangular":
            half = item.u * math.sqrt(3.0)
            samples[item.name] = item.value + rng.uniform(-half, half, draws)
        elif item.kind is EvalType.A and not math.isinf(item.dof) and item.dof > 2:
            scale = item.u * math.sqrt((item.dof - 2.0) / item.dof)
            samples[item.name] = item.value + scale * rng.standard_t(item.dof, draws)
        else:
            samples[item.name] = item.value + item.u * rng.standard_normal(draws)
    values = np.array([func({n: float(s[j]) for n, s in samples.items()}) for j in range(draws)])
    lo, hi = np.quantile(values, [0.025, 0.975])
    return float(values.mean()), float(values.std(ddof=1)), float(lo), float(hi)


def batch_mean_sem(samples: np.ndarray, n_batches: int = 10) -> tuple[float, float]:
    """Standard error of a mean of correlated samples, and its dof, by batch means.

    σ/√n is only right for white noise; a gyro's correlated noise (bias
    instability, rate random walk, Markov) makes it far too small. The mean of
    ``n_batches`` contiguous batches scatters with all noise slower than a
    batch, so std(batch means)/√n_b is the type A standard uncertainty with
    ν = n_b − 1 (the method of batch means; an Allan-variance argument at
    τ = T/n_b).
    """
    data = np.asarray(samples, dtype=float)
    size = data.size // n_batches
    if size < 2:
        raise ValueError(f"{data.size} samples cannot make {n_batches} batches")
    means = data[: size * n_batches].reshape(n_batches, size).mean(axis=1)
    return float(means.std(ddof=1) / math.sqrt(n_batches)), float(n_batches - 1)


def round_to_uncertainty(value: float, expanded: float | None) -> tuple[str, str]:
    """(value, U) as text: U to two significant digits, the value to U's last digit (GUM 7.2.6)."""
    if value is None or not math.isfinite(value):
        return "—", "—"
    if expanded is None or not math.isfinite(expanded) or expanded <= 0:
        return f"{value:.6g}", "—"
    exponent = math.floor(math.log10(expanded)) - 1     # the place of U's second digit
    decimals = max(0, -exponent)
    if decimals == 0:
        step = 10 ** exponent
        return f"{round(value / step) * step:.0f}", f"{round(expanded / step) * step:.0f}"
    return f"{value:.{decimals}f}", f"{expanded:.{decimals}f}"
