"""Effects this procedure cannot tell apart, their probabilities, and the experiment that would.

Under steady ramps a lagging sensor and a bias proportional to dT/dt leave
almost the same residual; with only a few rate levels |ω| and ω² do too.
Naming one of them as if certain would send the lab after the wrong cause,
so the best effect comes with every rival whose likelihood is close or whose
fitted signature is nearly collinear, each with a probability from the
likelihood gains (softmax of Δ log L = Δχ²/2, flat prior over the catalogue),
and with a procedure fragment that would separate them: a sequence in the
project's procedure language that the orchestrator can run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrocal.analysis.discrepancy.scoring import EffectScores

#: A rival enters the group when its probability is at least this ...
MIN_PROBABILITY = 0.01
#: ... or when its fitted signature correlates this much with the best one's.
MIN_CORRELATION = 0.9


@dataclass(frozen=True)
class LookAlike:
    name: str
    probability: float
    correlation: float


def probabilities(scores: dict[str, EffectScores]) -> dict[str, float]:
    """Softmax of Δχ²/2 over the scored effects (a flat prior over the catalogue)."""
    names = list(scores)
    if not names:
        return {}
    half = np.array([max(scores[n].delta_chi2, 0.0) / 2.0 for n in names])
    weights = np.exp(half - half.max())
    weights /= weights.sum()
    return dict(zip(names, weights.tolist(), strict=True))


def real_probability(score: float, threshold: float) -> float:
    """Probability that an accepted claim is not a noise fluke: odds 10^(score − threshold).

    Both are −log10 tail probabilities on one scale, the threshold calibrated by
    simulation to the (1 − α) point of the best effect-free score over the whole
    library; their difference is the log of how much rarer the claim is than
    the worst fluke the search lets through. A claim right at the threshold is a
    coin toss (0.5), one decade above it 0.91, two 0.99. The look-alike split is
    applied on top of it. docs/discrepancy-validation.md holds the reliability
    diagram this is judged by (of claims near 0.9, how many were right).
    """
    return 1.0 / (1.0 + 10.0 ** (-(score - threshold)))


@dataclass(frozen=True)
class TailVerdict:
    """A residual test's outcome as −log10 tail probabilities: its statistic and its family-wise point.

    One owner for what the window scan and the harmonic comb both say about a finding: it
    fires above the point, and the share of the data the named effects still account for is
    one minus the finding's odds (``real_probability``), 1 when it does not fire.
    """

    statistic: float        # −log10 of the smallest tail probability the test saw
    threshold: float        # −log10 of its family-wise point

    @property
    def fires(self) -> bool:
        return self.statistic > self.threshold

    @property
    def whole_account(self) -> float:
        return 1.0 - real_probability(self.statistic, self.threshold) if self.fires else 1.0


def _correlation(a: np.ndarray | None, b: np.ndarray | None) -> float:
    if a is None or b is None:
        return 0.0
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na == 0 or nb == 0:
        return 0.0
    return float(abs(a @ b) / (na * nb))


def lookalike_group(best: str, scores: dict[str, EffectScores]) -> tuple[float, list[LookAlike]]:
    """The best effect's probability within its group, and its rivals (most probable first).

    Probabilities are renormalised within the group, so they say how the data
    split between the candidates this procedure cannot separate.
    """
    prob = probabilities(scores)
    reference = scores[best].best.white_contribution
    members: list[tuple[str, float, float]] = []
    for name, effect in scores.items():
        if name == best or effect.delta_chi2 <= 0:
            continue
        corr = _correlation(reference, effect.best.white_contribution)
        if prob[name] >= MIN_PROBABILITY or corr >= MIN_CORRELATION:
            members.append((name, prob[name], corr))
    total = prob[best] + sum(p for _, p, _ in members)
    rivals = sorted((LookAlike(n, p / total, c) for n, p, c in members), key=lambda x: -x.probability)
    return prob[best] / total, rivals


def _two_ramp_rates(hold_min: int) -> list[str]:
    """The thermal look-alikes' fragment: a slow and a fast ramp, each followed by a soak."""
    soak = f"    soak: {{tolerance_c: 0.3, hold: {hold_min} min, max_wait: {hold_min + 120} min}}"
    return [
        "# two ramp rates: a lag shifts the temperature by rate·tau (grows with the rate) and",
        "# settles within 3·tau in the soak; a dT/dt bias stops the moment the ramp stops.",
        "sequence:",
        "  - setpoint_c: 45.0",
        "    ramp_c_per_min: 0.5",
        soak,
        f"    tests: [{{kind: static, duration: {hold_min} min}}]",
        "  - setpoint_c: 5.0",
        "    ramp_c_per_min: 3.0",
        soak,
        f"    tests: [{{kind: static, duration: {hold_min} min}}]",
        "  - setpoint_c: 25.0",
        "    ramp_c_per_min: 1.0",
        soak,
        "    tests: [{kind: static, duration: 30 min}]",
    ]


def separating_experiment(best: str, rivals: list[str], tau_s: float | None = None,
                          rate_levels_dps: tuple[float, ...] = ()) -> str:
    """A YAML procedure fragment (a ``sequence``) that separates ``best`` from ``rivals``.

    Empty when there is no rival. The fragment uses the keys of the project's
    procedure files (setpoint_c, ramp_c_per_min, soak, tests) and is meant to
    be appended to a procedure's sequence.
    """
    if not rivals:
        return ""
    group = {best, *rivals}
    lines = [f"# separates {best} from {', '.join(rivals)}"]
    thermal = {"thermal_lag", "temp_rate_bias", "temp_hysteresis", "bias_temp_quadratic",
               "sf_temp_quadratic"}
    rate = {"sf_nonlinearity_quadratic", "sf_nonlinearity_cubic", "sf_asymmetry", "dead_zone"}
    slow = {"warmup_transient", "bias_ramp"}
    hold_min = max(30, int(math.ceil(3.0 * (tau_s or 600.0) / 60.0)))
    if group & thermal:
        lines += _two_ramp_rates(hold_min)
    elif group & rate:
        top = max(rate_levels_dps, default=200.0)
        levels = sorted({round(float(x), 3) for x in np.geomspace(0.1, max(top, 1.0), 12)})
        lines += [
            "# a dense rate sweep in both directions: |w| and w^2 differ in curvature between",
            "# the levels, a dead band only below its threshold, an odd term changes sign.",
            "sequence:",
            "  - setpoint_c: 25.0",
            "    tests:",
            f"      - {{kind: sf_sweep, rates_dps: {levels}, directions: both, dwell: 60 s}}",
        ]
    elif group & slow:
        lines += [
            "# one long static hold from power-on: an exponential levels off after 3·tau,",
            "# a drift keeps going.",
            "sequence:",
            "  - setpoint_c: 25.0",
            f"    tests: [{{kind: static, duration: {max(120, 2 * hold_min)} min}}]",
        ]
    else:
        lines += [
            "# static holds at several table angles and a slow revolution at a steady temperature.",
            "sequence:",
            "  - setpoint_c: 25.0",
            "    tests:",
            "      - {kind: static, duration: 30 min}",
            "      - {kind: sf_sweep, rates_dps: [1, 2, 5], directions: both, dwell: 360 s}",
        ]
    return "\n".join(lines) + "\n"
