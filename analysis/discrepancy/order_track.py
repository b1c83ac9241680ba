"""A line locked to the table angle at order k ≥ 2 (motor cogging): order tracking across rate dwells.

A bias ∝ cos(k·θ − φ), θ the table angle (a drive motor's cogging, an encoder's
line count, a bearing's balls), is a line whose frequency in time is k·|ω|/360
Hz: a different one in every rate dwell. The fixed-line search (periodic.py)
sees a few weak lines, each holding the power of one rate's dwells; the
drifting-line search (line_drift.py) follows a frequency that moves slowly with
temperature or time, not one that jumps with the table's rate; the catalogue's
table_angle_harmonic is order 1 only. On the fourth held-out set (U1–U3) a
cogging line cos 24θ at 10σ was neither named nor called unexplained on U2 and
U3 (4 of 4 runs silent). Rotating-machinery analysis reads such a line in the
order domain, against the shaft angle instead of time; so does this test.

In every constant-rate turning dwell (segments.py: a segment whose rate is
constant and not zero; consecutive ones at one rate joined) the full-rate
residual of the last refit, less a cubic in time (slow structure, named or
not, would otherwise leak into the lowest orders of a short dwell: an
unnamed narrow-band process at 0.004 Hz fired order 142 with the mean and
slope alone), is read at the
frequencies k·|ω|/360 of every integer order k from 2 up (one chirp-z
transform per dwell, exact at those frequencies): its complex amplitude
against cos/sin(kθ), θ the dwell's table angle (a straight-line fit of the
angle the model uses). An order enters from a dwell only where it is not
aliased (k·|ω|/360 ≤ ``NYQUIST_USE`` of the Nyquist frequency) and completes at
least ``MIN_CYCLES`` cycles there. The dwells' amplitudes are pooled
coherently, each weighted by its inverse noise variance from the noise
model's PSD at its frequency (times one level over all dwells, the median of
their normalised periodograms, robust to the line itself, as periodic.py has
it): under the noise model the pooled power of one order is Exp(1), and the
coherent sum collects a line fixed to the angle from every dwell and rate
while a fixed-frequency line, at another order in each rate and with no phase
relation to θ from one dwell to the next, adds up incoherently.

The threshold is the max over the orders tested: P(max of K Exp(1) > x) =
1 − (1 − e^{−x})^K at ``ORDER_ALPHA`` = 0.5 % (the false alarms this test may
add); neighbouring orders of a short dwell are correlated, which only makes
the bound conservative. (No simulation is needed for that null: the
statistic's distribution under the noise model is exact; effect-free records
through the whole workflow measure what the bound leaves, in
docs/discrepancy-validation.md.) Order 1 is table_angle_harmonic's and is not
tested.

When the line is there the result is ``unexplained``, ``where`` names the order,
its amplitude and phase and the frequencies it took in the dwells; a named
periodic_interference at one of those frequencies, any named deterministic
effect that no longer adds once the order line is taken out of the data, and a
named markov_bias that no longer clears its threshold without the line, keep only ``1 − real_probability(score, threshold)`` of their
probability (the adequacy test's odds rule).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import CZT, czt

from gyrocal.analysis.discrepancy.adequacy import NOT_JUDGED
from gyrocal.analysis.discrepancy.candidates import PERIODIC
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.periodic import max_exponential_score
from gyrocal.analysis.discrepancy.result import DiscrepancyResult, FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit, gls_fit, score_from_delta
from gyrocal.analysis.discrepancy.signatures import effect_columns
from gyrocal.analysis.discrepancy.stochastic import MARKOV, WhittleTest, fine_bins

#: False alarms the test may add (the max over every order tested).
ORDER_ALPHA = 0.005
#: Lowest order tested: order 1 is the catalogue's table_angle_harmonic.
MIN_ORDER = 2
#: Highest order tested (motor cogging and encoder lines sit well below).
MAX_ORDER = 4096
#: An order's frequency must be below this fraction of the Nyquist frequency (no aliasing, no
#: anti-alias roll-off) and complete this many cycles in a dwell for the dwell to read it.
NYQUIST_USE = 0.9
MIN_CYCLES = 2.0
#: Degree of the polynomial taken out of each dwell first (slow structure would leak into the lowest orders).
DETREND_DEGREE = 3
#: Above this many cycles in a dwell the cubic's share of a line is below 1e-3 and is not computed.
PROJECTED_CYCLES = 40.0
#: Most turning samples read: a longer record's dwells are each cut to their share of it (chosen
#: from the rates alone, never from the residual, so the bound holds). A 10 M-sample overnight log
#: would otherwise cost about 2 s; 2^21 samples cost what a 3-hour, 200 Hz procedure does.
MAX_SAMPLES = 1 << 21
#: Shortest turning dwell read (samples), and the smallest rate that counts as turning (deg/s).
MIN_SAMPLES = 32
MIN_RATE_DPS = 1e-3


@dataclass(frozen=True)
class Dwell:
    """A constant-rate turning stretch of the record: samples [start, stop), rate, angle at start."""

    start: int
    stop: int
    rate_dps: float
    theta0_deg: float

    @property
    def n(self) -> int:
        return self.stop - self.start

    def orders(self, fs_hz: float) -> tuple[int, int]:
        """(lowest, highest) order this dwell reads: enough cycles, not aliased, within the range."""
        turns = abs(self.rate_dps) * self.n / fs_hz / 360.0
        lo = max(MIN_ORDER, math.ceil(MIN_CYCLES / max(turns, 1e-12)))
        hi = min(MAX_ORDER, math.floor(NYQUIST_USE * 0.5 * fs_hz * 360.0 / abs(self.rate_dps)))
        return lo, hi


@dataclass(frozen=True)
class OrderLine:
    """The strongest order of the pooled order spectrum and the test's figures."""

    order: int
    amplitude_dph: float
    phase_deg: float
    power: float                    # pooled coherent power (Exp(1) under the noise model)
    n_orders: int                   # orders tested (the max's count)
    n_dwells: int                   # dwells that read this order
    rates_dps: tuple[float, ...]    # the distinct |rates| of those dwells
    spans_hz: tuple[tuple[float, float], ...]   # per dwell that read it: its frequency ± resolution

    @property
    def score(self) -> float:
        return max_exponential_score(self.power, self.n_orders)

    @property
    def threshold(self) -> float:
        return -math.log10(ORDER_ALPHA)

    @property
    def fires(self) -> bool:
        return self.score > self.threshold

    @property
    def whole_account(self) -> float:
        return 1.0 - real_probability(self.score, self.threshold)

    def describe(self) -> str:
        freqs = ", ".join(f"{self.order * r / 360.0:.3g} Hz at {r:g} deg/s" for r in self.rates_dps[:4])
        more = "" if len(self.rates_dps) <= 4 else f" and {len(self.rates_dps) - 4} more rates"
        return (f"a line locked to the table angle at order {self.order} (bias {self.amplitude_dph:.3g} deg/h·"
                f"cos({self.order}θ − {self.phase_deg:.0f}°), {self.order} cycles per turn: {freqs}{more}; "
                f"coherent over {self.n_dwells} turning dwells, power {self.power:.0f}; score {self.score:.1f}, "
                f"threshold {self.threshold:.1f} over {self.n_orders} orders)")

    def shape_dph(self, angle_deg: np.ndarray) -> np.ndarray:
        return self.amplitude_dph * np.cos(np.deg2rad(self.order * np.asarray(angle_deg) - self.phase_deg))


def turning_dwells(rate_dps: np.ndarray, angle_deg: np.ndarray, slices, fs_hz: float) -> list[Dwell]:
    """Constant-rate turning segments (consecutive ones at one rate joined), angle by a line fit."""
    runs: list[list[int]] = []
    for s in slices:
        r = rate_dps[s]
        if r.size == 0 or np.ptp(r) > 1e-3 + 1e-6 * float(np.max(np.abs(r))) or abs(float(r[0])) < MIN_RATE_DPS:
            continue
        if runs and runs[-1][1] == s.start and rate_dps[runs[-1][0]] == r[0]:
            runs[-1][1] = s.stop
        else:
            runs.append([s.start, s.stop])
    dwells = []
    for a, b in runs:
        if b - a < MIN_SAMPLES:
            continue
        t = np.arange(b - a) / fs_hz
        slope, theta0 = np.polyfit(t, np.asarray(angle_deg[a:b], dtype=float), 1)
        dwells.append(Dwell(a, b, float(slope), float(theta0)))
    return dwells


def order_scan(resid_dph: np.ndarray, angle_deg: np.ndarray, rate_dps: np.ndarray, slices, fs_hz: float,
               noise: NoiseModel) -> OrderLine | None:
    """The pooled order spectrum of the residual's turning dwells and its strongest order (None: none read).

    One dwell's plan at a time (its basis and chirp-z set up, read, let go): the memory of
    one dwell, not of all of them, as an ``OrderPlan`` would hold."""
    dwells = scanned_dwells(angle_deg, rate_dps, slices, fs_hz)
    if not dwells:
        return None
    parts = [_DwellPlan.of(d, fs_hz, noise).read(resid_dph) for d in dwells]
    return _pooled(dwells, parts, fs_hz)


@dataclass(frozen=True)
class OrderPlan:
    """Everything of ``order_scan`` that the residual does not enter, set up once for many residuals
    on one record (a null distribution's draws): ``plan.scan(resid)`` is ``order_scan(resid, ...)``
    bit for bit, at about a quarter of its cost (the chirp-z set-up and the noise PSD at every
    order are most of a scan). It holds every dwell's cubic basis and chirp-z at once."""

    dwells: tuple[Dwell, ...]
    parts: tuple[_DwellPlan, ...]
    fs_hz: float

    @classmethod
    def of(cls, angle_deg: np.ndarray, rate_dps: np.ndarray, slices, fs_hz: float,
           noise: NoiseModel) -> OrderPlan | None:
        dwells = scanned_dwells(angle_deg, rate_dps, slices, fs_hz)
        if not dwells:
            return None
        return cls(tuple(dwells), tuple(_DwellPlan.of(d, fs_hz, noise) for d in dwells), fs_hz)

    def scan(self, resid_dph: np.ndarray) -> OrderLine:
        return _pooled(list(self.dwells), [p.read(resid_dph) for p in self.parts], self.fs_hz)


def scanned_dwells(angle_deg: np.ndarray, rate_dps: np.ndarray, slices, fs_hz: float) -> list[Dwell]:
    """The turning dwells the scan reads: cut to their share of ``MAX_SAMPLES``, each reading an order."""
    dwells = turning_dwells(rate_dps, angle_deg, slices, fs_hz)
    total = sum(d.n for d in dwells)
    if total > MAX_SAMPLES:
        dwells = [replace(d, stop=d.start + int(d.n * MAX_SAMPLES / total)) for d in dwells]
    return [d for d in dwells if d.n >= MIN_SAMPLES and d.orders(fs_hz)[0] <= d.orders(fs_hz)[1]]


def _pooled(dwells: list[Dwell], parts: list[_DwellOrders], fs_hz: float) -> OrderLine:
    """The dwells' amplitudes pooled coherently at each order; the strongest order and its figures."""
    level = float(np.median(np.concatenate([p.ratios for p in parts]))) / math.log(2.0)
    top = max(p.orders[-1] for p in parts) + 1
    num = np.zeros(top, dtype=complex)
    den = np.zeros(top)
    for p in parts:
        num[p.orders] += p.weight * p.coef / level
        den[p.orders] += p.weight / level
    tested = np.flatnonzero(den > 0)
    power = np.abs(num[tested]) ** 2 / den[tested]
    k = int(tested[int(np.argmax(power))])
    amplitude = num[k] / den[k]
    used = [(d, p) for d, p in zip(dwells, parts, strict=True) if p.orders[0] <= k <= p.orders[-1]]
    return OrderLine(k, float(abs(amplitude)), float(np.degrees(-np.angle(amplitude)) % 360.0),
                     float(np.max(power)), int(tested.size), len(used),
                     tuple(sorted({round(abs(d.rate_dps), 6) for d, _ in used})),
                     tuple(_span(d, k, fs_hz) for d, _ in used))


@dataclass(frozen=True)
class _DwellOrders:
    orders: np.ndarray      # integer orders read
    coef: np.ndarray        # complex amplitude c with bias = Re(c·e^{ikθ}) = |c|·cos(kθ + arg c)
    weight: np.ndarray      # 1 / E|c|² under the noise model
    ratios: np.ndarray      # the dwell's periodogram over the noise PSD (for the common level)


@dataclass(frozen=True)
class _DwellPlan:
    """One dwell's reading of its integer orders (chirp-z at k·|ω|/360 Hz), set up before the residual.

    A cubic in time is projected out first (P); the amplitude is then
    ⟨Px, e_k⟩/‖Pe_k‖² with e_k = e^{2πi f_k t}, which the projection does not bias (with
    the mean and slope out alone, n in place of ‖Pe_k‖² read a line 3 % low in a dwell of
    3 cycles), and its variance under locally white noise of PSD S is 4·fs·S/‖Pe_k‖².
    No taper: a Hann window cost a third of the power and, with the cycles it needs, the
    slow dwells (order-24 power 45 → 22 on Q2).
    """

    dwell: Dwell
    basis: np.ndarray        # orthonormal cubic in time over the dwell (n × 4)
    transform: CZT           # the chirp-z at the dwell's orders
    kept: np.ndarray         # ‖Pe_k‖²: the cubic takes a share only of the first cycles
    orders: np.ndarray
    turn: np.ndarray         # e^{−ik·θ0}: amplitudes referred to the dwell's start angle
    weight: np.ndarray
    band: np.ndarray         # the periodogram's bins used for the common level
    band_psd: np.ndarray     # n·fs·S(f) at those bins

    @classmethod
    def of(cls, dwell: Dwell, fs_hz: float, noise: NoiseModel) -> _DwellPlan:
        n = dwell.n
        basis, _ = np.linalg.qr(np.vander(np.linspace(-1.0, 1.0, n), DETREND_DEGREE + 1))
        lo, hi = dwell.orders(fs_hz)
        df = abs(dwell.rate_dps) / 360.0
        w, a = np.exp(-2j * math.pi * df / fs_hz), np.exp(2j * math.pi * lo * df / fs_hz)
        kept = np.full(hi - lo + 1, float(n))
        few = min(hi - lo + 1, max(0, math.ceil(PROJECTED_CYCLES * 360.0 * fs_hz / (abs(dwell.rate_dps) * n)) - lo + 1))
        if few > 0:
            kept[:few] -= np.sum(np.abs(czt(basis.T, m=few, w=w, a=a, axis=-1)) ** 2, axis=0)
        orders = np.arange(lo, hi + 1)
        f = np.fft.rfftfreq(n, 1.0 / fs_hz)
        band = (f >= MIN_CYCLES * fs_hz / n) & (f < NYQUIST_USE * 0.5 * fs_hz)
        return cls(dwell, basis, CZT(n, m=hi - lo + 1, w=w, a=a), kept, orders,
                   np.exp(-1j * np.deg2rad(orders * dwell.theta0_deg)),
                   kept / (4.0 * fs_hz * noise.psd_two_sided(orders * df, fs_hz)),
                   band, n * fs_hz * noise.psd_two_sided(f[band], fs_hz))

    def read(self, resid_dph: np.ndarray) -> _DwellOrders:
        """The dwell's complex amplitudes at its orders, from the whole record's residual."""
        x = np.asarray(resid_dph[self.dwell.start:self.dwell.stop], dtype=float)
        x = x - self.basis @ (self.basis.T @ x)
        spectrum = self.transform(x)
        if self.dwell.rate_dps < 0:      # θ falls: the line's e^{ikθ} part sits at −k·|ω|/360
            spectrum = np.conj(spectrum)
        coef = 2.0 * spectrum / self.kept * self.turn
        ratios = np.abs(np.fft.rfft(x)[self.band]) ** 2 / self.band_psd
        return _DwellOrders(self.orders, coef, self.weight, ratios)


def _span(dwell: Dwell, order: int, fs_hz: float) -> tuple[float, float]:
    f = order * abs(dwell.rate_dps) / 360.0
    resolution = 2.0 * fs_hz / dwell.n
    return f - resolution, f + resolution


def with_order_line(ctx: Context, after: Fit, result: DiscrepancyResult) -> DiscrepancyResult:
    """The workflow's result once the order test has run on the final refit.

    Fired: ``unexplained``, the line first in ``where``, the named effects it
    replaces below their claim. Always: a note with the strongest order read.
    """
    line = order_scan(ctx.resid_full(after), ctx.builder.history.angle_deg, ctx.log.table_rate_dps,
                      ctx.segments.slices, ctx.fs_hz, ctx.noise)
    if line is None:
        return result
    note = (f"order tracking over {line.n_orders} orders of the table angle (2 and up) in the turning "
            f"dwells: strongest order {line.order}, power {line.power:.1f}, score {line.score:.1f} "
            f"against {line.threshold:.1f}")
    notes = [*result.notes, note]
    if not line.fires:
        return replace(result, notes=notes)
    where = f"{line.describe()}; {result.where}" if result.where else line.describe()
    return replace(result, found=judged_by_order(ctx, after, result.found, line), unexplained=True,
                   where=where, notes=notes)


def judged_by_order(ctx: Context, after: Fit, found: list[FoundEffect], line: OrderLine) -> list[FoundEffect]:
    """The named effects with the probabilities the order line leaves them.

    A named periodic_interference within the line's frequencies, a deterministic
    effect that no longer adds (its own threshold) once the order line is taken
    out of the data, and a markov_bias whose Whittle test no longer clears the
    threshold it was named at on the residual without the line (a line at low
    orders in slow dwells is excess power at a fraction of a hertz, which a
    Markov fit absorbs: 0.85 and 1.0 on two of our order-24 cases) keep only
    ``line.whole_account`` of their probability.
    """
    angle = ctx.builder.history.angle_deg
    judged = [f for f in found if f.name not in NOT_JUDGED]
    if judged:
        y_bins = ctx.bins.mean(ctx.y_full - line.shape_dph(angle))
        with_all = gls_fit(ctx.builder, ctx.whitener, y_bins, after.model).chi2
    out = []
    for f in found:
        if f.name == PERIODIC:
            freq = f.parameters.get("freq_hz", math.nan)
            replaced = any(lo <= freq <= hi for lo, hi in line.spans_hz)
        elif f.name == MARKOV:
            replaced = _markov_without_line(ctx, after, line, angle) <= f.threshold
        elif f.name in NOT_JUDGED:
            replaced = False
        else:
            without = gls_fit(ctx.builder, ctx.whitener, y_bins, after.model.without_effect(f.name)).chi2
            replaced = score_from_delta(without - with_all, max(len(effect_columns(f.name)), 1)) <= f.threshold
        out.append(replace(f, probability=f.probability * line.whole_account) if replaced else f)
    return out


def _markov_without_line(ctx: Context, after: Fit, line: OrderLine, angle_deg: np.ndarray) -> float:
    """The Markov test's score on the residual less the order line, against the noise model without it."""
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    noise = replace(ctx.noise, markov_sigma_dph=0.0, markov_tau_s=0.0)
    clean = ctx.resid_full(after) - line.shape_dph(angle_deg)
    return WhittleTest(noise, bins, ctx.fs_hz).test(bins.mean(clean), ctx.rng, ctx.n_null).score
