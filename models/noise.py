"""Stochastic rate noise w(t) of the gyro model, in deg/h, as streamable generators.

Each IEEE Std 952 term is a small stateful generator: calling ``generate(n1)``
then ``generate(n2)`` yields exactly the samples of one ``generate(n1 + n2)``
(each term draws from its own random stream and carries its filter state), so
a simulated gyro that is read block by block over a night is statistically
the same as one long record.

Unit bookkeeping (the equation's bracket is deg/h; τ and 1/fs are in s):

* 1 deg/√h = 60 deg/h·√s, because √h = 60·√s.
* 1 arcsec/s = 1 deg/h, because arcsec/s = (deg/3600)/s = deg/(3600 s).
* K in deg/h/√h = (K/60) deg/h/√s; R in deg/h/h = (R/3600) deg/h/s.

Allan variance of w (the targets the tests check with allantools):
σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π)·B² + K²τ/3 + R²τ²/2, with Q in arcsec,
N in deg/h·√s, K in deg/h/√s, R in deg/h/s and τ in s.
"""

from __future__ import annotations

import functools
import math
from typing import Protocol

import numpy as np

from gyrocal.models.allan_theory import (  # noqa: F401 - re-exported for the simulator's users
    FLICKER_FLOOR_PER_B,
    MARKOV_PEAK_TAU_PER_TC,
    markov_avar,
)
from gyrocal.models.gyro_model import NoiseParams
from gyrocal.models.recursion import first_order, first_order_sum

#: Correlation-time band of the Gauss-Markov bank that makes the flicker noise.
#: 0.1 s .. 1e6 s keeps the Allan floor flat from ~1 s to ~1e4 s (overnight
#: records); 3 processes per decade keep its ripple at a fraction of a percent.
FLICKER_TAU_MIN_S = 0.1
FLICKER_TAU_MAX_S = 1.0e6
FLICKER_PER_DECADE = 3



class NoiseTerm(Protocol):
    """One streamable noise term: successive calls continue the same process."""

    def generate(self, n: int) -> np.ndarray:
        """The next ``n`` samples of the term, deg/h."""


def _rng(seed: int | np.random.SeedSequence | None) -> np.random.Generator:
    return np.random.default_rng(seed)


class WhiteRateNoise:
    """Angle random walk N: white rate noise, σ per sample = 60·N·√fs deg/h."""

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_rng",)

    def __init__(self, arw_deg_per_rth: float, fs_hz: float, seed=None) -> None:
        self.sigma_dph = 60.0 * arw_deg_per_rth * math.sqrt(fs_hz)
        self._rng = _rng(seed)

    def generate(self, n: int) -> np.ndarray:
        return self.sigma_dph * self._rng.standard_normal(n)


class WhiteAngleNoise:
    """Quantization noise Q: white angle noise (std Q arcsec) seen as its rate.

    The rate is the sample-to-sample difference of the angle times fs, in
    arcsec/s = deg/h. The Allan variance of such a rate is exactly 3Q²/τ².
    The last angle sample is the state, so blocks join without a seam.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_rng", "_last_arcsec")

    def __init__(self, quantization_arcsec: float, fs_hz: float, seed=None) -> None:
        self.q_arcsec = quantization_arcsec
        self.fs_hz = fs_hz
        self._rng = _rng(seed)
        self._last_arcsec = self.q_arcsec * self._rng.standard_normal()

    def generate(self, n: int) -> np.ndarray:
        if n == 0:
            return np.zeros(0)
        angle_arcsec = self.q_arcsec * self._rng.standard_normal(n)
        previous = np.concatenate(([self._last_arcsec], angle_arcsec[:-1]))
        self._last_arcsec = float(angle_arcsec[-1])
        return (angle_arcsec - previous) * self.fs_hz


class RateRandomWalk:
    """Rate random walk K: rate increments of std (K/60)·√(1/fs) deg/h per sample."""

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_rng", "_level_dph")

    def __init__(self, rrw_deg_per_h_rth: float, fs_hz: float, seed=None) -> None:
        self.step_dph = rrw_deg_per_h_rth / 60.0 / math.sqrt(fs_hz)
        self._rng = _rng(seed)
        self._level_dph = 0.0

    def generate(self, n: int) -> np.ndarray:
        if n == 0:
            return np.zeros(0)
        out = self._level_dph + np.cumsum(self.step_dph * self._rng.standard_normal(n))
        self._level_dph = float(out[-1])
        return out


class RateRamp:
    """Rate ramp R: w = ±R·t, sign drawn once, so σ_A(τ) = R·τ/√2 for every draw.

    A ramp of slope R deg/h/h is R/3600 deg/h per second. The random sign keeps
    the term zero-mean over an ensemble of gyros while its Allan signature is
    exact for each one (a Gaussian slope would make it exact only on average).
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_index",)

    def __init__(self, rate_ramp_dph_per_h: float, fs_hz: float, seed=None) -> None:
        sign = 1.0 if _rng(seed).random() < 0.5 else -1.0
        self.slope_dph_per_s = sign * rate_ramp_dph_per_h / 3600.0
        self.fs_hz = fs_hz
        self._index = 0

    def generate(self, n: int) -> np.ndarray:
        t_s = (self._index + np.arange(n)) / self.fs_hz
        self._index += n
        return self.slope_dph_per_s * t_s


class GaussMarkov:
    """First-order Gauss-Markov process (steady-state std σ, correlation time T).

    Exact discretisation x_k = a·x_{k-1} + σ·√(1−a²)·ε_k, a = exp(−1/(fs·T)),
    started from its stationary distribution so the record has no transient.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_rng", "_x")

    def __init__(self, sigma_dph: float, tau_s: float, fs_hz: float, seed=None) -> None:
        if not tau_s > 0:
            raise ValueError(f"Gauss-Markov correlation time must be > 0, got {tau_s!r}")
        self.sigma_dph = sigma_dph
        self.tau_s = tau_s
        self._a = math.exp(-1.0 / (fs_hz * tau_s))
        self._gain = sigma_dph * math.sqrt(-math.expm1(-2.0 / (fs_hz * tau_s)))  # σ√(1−a²)
        self._rng = _rng(seed)
        self._x = sigma_dph * self._rng.standard_normal()

    @property
    def last_dph(self) -> float:
        """The most recent sample (the stationary start before the first call)."""
        return self._x

    def generate(self, n: int) -> np.ndarray:
        if n == 0:
            return np.zeros(0)
        out = first_order(self._gain, self._a, self._rng.standard_normal(n), self._x)
        self._x = float(out[-1])
        return out


def markov_allan_variance(tau_s, sigma_dph: float, tc_s: float) -> np.ndarray:
    """Allan variance (deg/h)² of a Gauss-Markov process: :func:`allan_theory.markov_avar`."""
    return markov_avar(tau_s, sigma_dph, tc_s)


def flicker_bank(bias_instability_dph: float) -> tuple[np.ndarray, np.ndarray]:
    """Correlation times (s) and stds (deg/h) of the Gauss-Markov bank for flicker B.

    A bank with ``n`` processes per unit ln T and equal variances σ_i² has the
    two-sided PSD Σ 2σ_i²T_i/(1+(2πfT_i)²) ≈ σ_i²·n/(2f) inside the band; the
    flicker law S(f) = B²/(2πf), whose Allan floor is √(2 ln2/π)·B, needs
    σ_i² = B²/(π·n) = B²·ln(r)/π for a spacing ratio r. A small correction,
    computed from the bank's exact Allan variance over 10..1000 s, removes the
    discretisation bias of the sum, so the floor is 0.664·B to a fraction of a
    percent there.
    """
    taus_s, sigma_each = _flicker_bank_per_b()
    return taus_s.copy(), np.full(taus_s.size, sigma_each * bias_instability_dph)


@functools.lru_cache(maxsize=1)
def _flicker_bank_per_b() -> tuple[np.ndarray, float]:
    """The bank's correlation times and its std per unit B: computed once, since neither depends
    on B (the discrepancy analysis asks for the noise PSD, hence the bank, some 170 times a
    workflow; its correction sums 22 Allan variances, ~1 ms a call)."""
    decades = math.log10(FLICKER_TAU_MAX_S / FLICKER_TAU_MIN_S)
    count = int(round(decades * FLICKER_PER_DECADE)) + 1
    taus_s = np.logspace(
        math.log10(FLICKER_TAU_MIN_S), math.log10(FLICKER_TAU_MAX_S), count
    )
    ratio = taus_s[1] / taus_s[0]
    sigma_each = math.sqrt(math.log(ratio) / math.pi)  # per unit B
    probe_tau_s = np.logspace(1, 3, 21)
    floor = np.sqrt(
        np.mean(sum(markov_allan_variance(probe_tau_s, sigma_each, t) for t in taus_s))
    )
    sigma_each *= FLICKER_FLOOR_PER_B / floor
    taus_s.setflags(write=False)
    return taus_s, sigma_each


class _DecimatedMarkovSum:
    """Sum of slow Gauss-Markov processes stepped once every ``decimation`` samples.

    A process with correlation time T carries almost no power above 1/T, so it
    is generated exactly on a coarse knot grid (step Δ ≤ T/50) and linearly
    interpolated in between; the interpolation lowers its variance by about
    Δ/(3T) < 0.7 %, only at frequencies where the faster processes dominate.
    Knot indices are absolute, so any split into blocks gives the same samples.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("processes", "_knots", "_first_knot", "_index")

    def __init__(self, processes: list[GaussMarkov], decimation: int) -> None:
        self.processes = processes
        self.decimation = decimation
        self._knots = np.array([sum(p.last_dph for p in processes)])  # knot 0 = stationary start
        self._first_knot = 0
        self._index = 0

    def generate(self, n: int) -> np.ndarray:
        if n == 0:
            return np.zeros(0)
        d = self.decimation
        sample = self._index + np.arange(n)
        needed = (self._index + n - 1) // d + 1  # the knot after the last sample
        have = self._first_knot + len(self._knots) - 1
        if needed > have:
            fresh = _bank_generate(self.processes, needed - have)
            self._knots = np.concatenate((self._knots, fresh))
        knot_sample = (self._first_knot + np.arange(len(self._knots))) * float(d)
        out = np.interp(sample.astype(float), knot_sample, self._knots)
        self._index += n
        keep_from = self._index // d - self._first_knot
        self._knots = self._knots[keep_from:]
        self._first_knot += keep_from
        return out


def _bank_generate(processes: list[GaussMarkov], n: int) -> np.ndarray:
    """``sum(p.generate(n) for p in processes)``, bit for bit, in one compiled call: each
    process draws its ``n`` normals from its own stream (into a row of one array, the
    same draws) and the recursions are run and summed together (``recursion.py``)."""
    drives = np.empty((len(processes), n))
    for row, process in zip(drives, processes, strict=True):
        process._rng.standard_normal(out=row)
    lasts = np.array([p._x for p in processes])
    out = first_order_sum(np.array([p._gain for p in processes]), np.array([p._a for p in processes]),
                          lasts, drives)
    for process, last in zip(processes, lasts.tolist(), strict=True):
        process._x = last
    return out


#: Knot steps (in samples) available to the flicker bank; a process uses the
#: largest one that is at most T/50.
_DECIMATIONS = (1, 64, 4096, 262144)
_KNOTS_PER_TAU = 50.0


class FlickerNoise:
    """Bias instability B: a bank of Gauss-Markov processes approximating 1/f noise.

    Slow processes run on decimated knot grids (see :class:`_DecimatedMarkovSum`),
    which makes the bank ~3x cheaper at 200 Hz without changing its Allan floor.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("groups",)

    def __init__(self, bias_instability_dph: float, fs_hz: float, seed=None) -> None:
        taus_s, sigmas_dph = flicker_bank(bias_instability_dph)
        base = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        seeds = base.spawn(len(taus_s))
        groups: dict[int, list[GaussMarkov]] = {}
        for tau_s, sigma_dph, sq in zip(taus_s, sigmas_dph, seeds, strict=True):
            d = max(x for x in _DECIMATIONS if x == 1 or x / fs_hz <= tau_s / _KNOTS_PER_TAU)
            groups.setdefault(d, []).append(GaussMarkov(sigma_dph, tau_s, fs_hz / d, sq))
        self.groups = [_DecimatedMarkovSum(procs, d) for d, procs in sorted(groups.items())]

    def generate(self, n: int) -> np.ndarray:
        out = np.zeros(n)
        for group in self.groups:
            out += group.generate(n)
        return out


# Fixed stream slots: adding or removing one term never changes another's draws.
# (IEEE symbols of models/noise_terms.py; the order is the draw order, not the table's)
_SLOTS = ("N", "Q", "B", "K", "R", "markov")


class NoiseGenerator:
    """The whole w(t): the IEEE terms of ``noise`` plus an optional Markov term.

    Terms with a zero coefficient cost nothing. ``seed`` (int, SeedSequence or
    None) seeds one independent stream per term.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("terms",)

    def __init__(
        self,
        noise: NoiseParams,
        fs_hz: float,
        seed: int | np.random.SeedSequence | None = None,
        markov: tuple[float, float] | None = None,
    ) -> None:
        if not fs_hz > 0:
            raise ValueError(f"sample rate must be > 0 Hz, got {fs_hz!r}")
        base = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        slot = dict(zip(_SLOTS, base.spawn(len(_SLOTS)), strict=True))
        self.terms: dict[str, NoiseTerm] = {}
        if noise.arw_deg_per_rth > 0:
            self.terms["N"] = WhiteRateNoise(noise.arw_deg_per_rth, fs_hz, slot["N"])
        if noise.quantization_arcsec > 0:
            self.terms["Q"] = WhiteAngleNoise(noise.quantization_arcsec, fs_hz, slot["Q"])
        if noise.bias_instability_dph > 0:
            self.terms["B"] = FlickerNoise(noise.bias_instability_dph, fs_hz, slot["B"])
        if noise.rrw_deg_per_h_rth > 0:
            self.terms["K"] = RateRandomWalk(noise.rrw_deg_per_h_rth, fs_hz, slot["K"])
        if noise.rate_ramp_dph_per_h > 0:
            self.terms["R"] = RateRamp(noise.rate_ramp_dph_per_h, fs_hz, slot["R"])
        if markov is not None and markov[0] > 0:
            self.terms["markov"] = GaussMarkov(markov[0], markov[1], fs_hz, slot["markov"])

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """Draw from ``seed`` from now on; every filter, walk and Markov state carries on.

        One child stream per slot (and per flicker process), as at construction,
        so adding a term never changes another's draws.
        """
        slot = dict(zip(_SLOTS, seed.spawn(len(_SLOTS)), strict=True))
        for name, term in self.terms.items():
            holders = ([p for group in term.groups for p in group.processes]
                       if isinstance(term, FlickerNoise) else [term])
            for holder, child in zip(holders, slot[name].spawn(len(holders)), strict=True):
                if hasattr(holder, "_rng"):
                    holder._rng = np.random.default_rng(child)

    def generate(self, n: int) -> np.ndarray:
        """The next ``n`` samples of w(t), deg/h (zeros when the model is noise-free)."""
        out = np.zeros(n)
        for term in self.terms.values():
            out += term.generate(n)
        return out
