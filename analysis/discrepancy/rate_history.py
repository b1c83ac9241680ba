"""Shapes in the table's rate history: a bias that remembers how the table has turned.

Two rig effects depend on what the table did before, not on the rate now, and the
catalogue has neither (on the third held-out set both drew wrong names at ≥ 0.8:
spin heating → markov_bias and sf_asymmetry, cable wind-up → bias_ramp and sf_asymmetry):

* **Spin heating.** A spinning table dissipates power in its bearings, seals, slip rings
  and motor: Coulomb friction gives P = T_c·|ω|, viscous friction and windage P = b·ω².
  The heat reaches the gyro through the mount, a first-order thermal path of time
  constant τ (minutes for a mount of a few kg), and the gyro's bias follows its own
  temperature, which the logged chamber temperature does not see. So the bias is
  |ω|ᵖ (p = 1 or 2) through a first-order memory: the catalogue's sf_asymmetry (∝ |ω|)
  and sf_nonlinearity_quadratic (∝ ω²) are its τ → 0 limit, thermal_lag lags the
  *chamber* temperature, and a Markov bias is what its slow tail looked like otherwise.
  The filter has unit gain, so the coefficient is the bias the heat settles to after a
  long spin (deg/h per deg/s or per (deg/s)²), and it starts from zero (the table at rest
  before the record).
* **Cable wind-up.** A table turned without slip rings (or a gyro cable led through a
  cable wrap) twists its harness by the net angle turned, ∫ω dt; the twisted cable
  pulls on the mount with a torque ∝ its twist (Hooke) and strains the sensor, whose
  bias moves in proportion and comes back as the table turns back. On a ± dwell pair the
  net angle rises and falls (a triangle whose bin means look like |ω|, sf_asymmetry);
  one-way slow turns add a staircase that a bias ramp approximates.

Both are evaluated on the samples' grid or on equal bins with the same formula
(``first_order_memory``), exact for an input held constant over each step.

Measured on own cases (``benchmarks/validate_rate_history.py``; docs/discrepancy-validation.md,
"Rate-history probes"): profiles P1, Q1–Q3 at 10σ by known-shape SNR, spin heating ω² τ 150
and 800 s and |ω| τ 400 s, net turns, 2 seeds each. Before these probes 23 of 32 runs were
`unexplained` (described as a slow sinusoid, a bias by rate sign, a cubic in time) and 10 had a
wrong claim ≥ 0.8 (net turns → bias_ramp 0.86–1.0 in 6 of 8, spin heating on Q2 →
markov_bias 0.91–1.0 in 4 of 6); after, 31 of 32 `unexplained` with the probe in ``where`` and
1 wrong claim ≥ 0.8 (net turns on Q2, bias_ramp 0.96; 7 of 8 seeds there `unexplained`: Q2's
net angle is mostly the staircase of its one-way turns, and 4.9σ of the 10σ is left once a
ramp is fitted). The 10σ neighbours (markov_bias τ 300 s, sf_asymmetry, bias_ramp,
warmup_transient, sf_nonlinearity_quadratic, thermal_lag; 48 runs) named first 45 of 48
before and after, 47 runs identical, one bias_ramp at 0.98 instead of 0.99. Effect-free: 300
controls (P1, Q1, Q2) no claim ≥ 0.8 and no `where` naming these probes; on 3000 null draws
each of P1, Q1–Q3, P2 the adequacy family fires 0–1 times more with them. CPU: 0.016 s for the
first call on a P2-sized record (930 000 samples, 2000 bins, 500 null draws), 0.01 s each
later call; 0.09 s first call on 10 M samples (``benchmarks/bench_rate_history_probes.py``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

_TURN_DEG = 360.0


def first_order_memory(u: np.ndarray, step_s: float, tau_s: float) -> np.ndarray:
    """Each step's mean of u (held over its step) through 1/(1 + sτ), from a zero start.

    With a = e^(−w/τ) the state at a step's end is y_k = a·y_{k−1} + (1 − a)·u_k, and its mean
    over the step is g·y_{k−1} + (1 − g)·u_k with g = (τ/w)(1 − a): the bin mean of the lagged
    signal, not the lagged bin mean, so τ of a bin or two keeps its shape.
    """
    ratio = step_s / tau_s
    a = math.exp(-ratio)
    g = -math.expm1(-ratio) / ratio
    end = lfilter([1.0 - a], [1.0, -a], u)
    before = np.concatenate([[0.0], end[:-1]])
    return g * before + (1.0 - g) * u


def net_turns(rate_dps: np.ndarray, step_s: float) -> np.ndarray:
    """The net table angle turned since the record's start, in turns (∫ω dt / 360°), per sample."""
    return np.cumsum(rate_dps) * (step_s / _TURN_DEG)
