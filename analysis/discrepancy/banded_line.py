"""A spectral line present in part of the record only: found, and told from a constant line.

The catalogue's periodic_interference (periodic.py) looks for one line of
constant amplitude in the spectrum of the whole record. A line that is there
only part of the time — a table bearing or motor-drive tone at high rates, a
chamber fan that runs while cooling, a line whose amplitude follows |ω| — is
diluted by every sample without it: in a part holding a fraction p of the
samples it collects p·n·A²/(4σ²) of normalised power, the whole record only
p² of that, below the noise maximum. On the third held-out set a line near
0.37·fs whose amplitude follows |ω| was neither named nor called unexplained
in any of its 5 runs.

The test takes the periodogram of the final residual (a named
periodic_interference put back, as line_drift.py does) restricted to parts of
the record — |rate| at or above a few of its quantiles, the |ω|-weighted
record (the matched filter of an amplitude ∝ |ω|), the table at rest,
chamber temperature below/above its median, heating, cooling, each quarter of
the time — each a weight per sample (0/1, or |ω|). Before weighting, each
bin mean of the residual is removed (everything below the bins' Nyquist is
the bin-mean tests' business, and a slow residual cut by a part's edges would
leak across the band). Divided by Σw²·fs·PSD and by its median over the band
(as periodic.py does), each Fourier bin of noise is Exp(1) in every part.

(a) Whether there is a line: the largest normalised power over every part and
every frequency from the bins' Nyquist to the record's, against the union
bound over all those cells (``max_exponential_score``), at ``ALPHA_BANDED`` =
0.2 % nominal. At 0.5 % nominal it fired on 6 of 400 effect-free draws (P1,
Q2, Q3): the threshold sits near 17–19 Exp(1) units, where a level a few per
cent off multiplies the tail (e^(s·δ)); the PSD's shape read from the whole
record (``_shape``) and the non-circular covariance (``_normalised``) did not
remove it on P1, so the bound is set lower to keep the measured rate within
the 0.5 % this test may add.
(b) Whether it is only in part: the part's power (½Δχ² of a sine fitted there
alone) must beat the whole record's at the same frequency (½Δχ² of the
catalogue's constant sine, the same two parameters) by ln(parts/``PART_ALPHA``),
the union bound over the parts tried. A constant line gives each part only its
share p of the whole record's power, so it never passes; periodic_interference
keeps it.

Measured (benchmarks/validate_banded_line.py, the test on the base refit):
effect-free controls fired 1 of 700 (P1, Q2, Q3 200 each, Q1 100); 10σ (‖s‖/σ)
lines found as part-only: ∝ |ω| at 0.29·fs 50 of 50 on P1, Q1, Q2, Q3 each;
∝ |ω|⁶ 25 of 50 on P1 (5 Hz: few top-rate samples), 50 of 50 on Q1–Q3; only
while cooling 50 of 50 on all four; a constant 10σ line part-only 0 of 200.
CPU 0.004–0.05 s on those, 0.39 s on P2 (930,000 samples, 27 single-precision
FFTs), 0.3 s on 10 M samples (the ``window``). In the workflow, 10σ
periodic_interference, markov_bias (τ 30, 300 s), sf_nonlinearity_quadratic/
cubic, temp_rate_bias and controls on P1 and Q2 (2 seeds each): 28 of 28 runs
unchanged.

When both hold the result is unexplained, ``where`` gives the frequency and
the part, and a periodic_interference named within two Fourier bins of the
line keeps only the probability that it is the whole account (the adequacy
test's odds rule, adequacy.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import fft as sp_fft

from gyrocal.analysis.discrepancy.candidates import PERIODIC, QUANTIZATION
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.line_drift import DriftLine, window
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.periodic import max_exponential_score, sine_dph
from gyrocal.analysis.discrepancy.quantization import line_within_quantization
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit
from gyrocal.analysis.discrepancy.segments import RATE_CHANGE_DPS

#: False alarms the detection adds at most (union bound over parts × frequencies).
ALPHA_BANDED = 0.002
#: Level of "only in part" (a constant line called part-only), union bound over the parts.
PART_ALPHA = 0.005
#: A part holds at least this share of the samples (fewer: its spectrum is too coarse to use).
MIN_PART_SHARE = 0.02
#: Quantiles of |rate| over the moving samples whose "at or above" parts are tried.
RATE_QUANTILES = (0.5, 0.75, 0.9)
#: Chamber temperature rate (degC/min) beyond which a sample is heating or cooling, and the
#: span (s) over which it is read.
TEMP_RATE_C_PER_MIN = 0.1
TEMP_RATE_SPAN_S = 60.0
#: Blocks of the whole record's spectrum the PSD's shape is read from (``_shape``).
SHAPE_BLOCKS = 32
#: Lowest level (over the noise model's PSD) a part's periodogram is divided by.
MIN_LEVEL = 0.5
#: Fewer band bins than this: nothing is judged.
_MIN_BAND_BINS = 32


@dataclass(frozen=True)
class Part:
    """A part of the record as a weight per sample, and how to speak of it."""

    key: str
    weight: np.ndarray
    phrase: str


@dataclass(frozen=True)
class BandedLine:
    """The strongest line over the parts, and both tests' figures."""

    part: str
    phrase: str
    freq_hz: float
    power: float           # the part's normalised power at the line (Exp(1) under noise)
    amplitude_dph: float   # the line's amplitude where the part's weight is 1
    whole_power: float     # the whole record's at the same frequency
    n_cells: float         # parts × band bins (the union bound's count)
    n_parts: int

    @property
    def score(self) -> float:
        return max_exponential_score(self.power, self.n_cells)

    @property
    def threshold(self) -> float:
        return -math.log10(ALPHA_BANDED)

    @property
    def present(self) -> bool:
        return self.score > self.threshold

    @property
    def part_margin(self) -> float:
        return math.log(max(self.n_parts, 1) / PART_ALPHA)

    @property
    def part_only(self) -> bool:
        return self.present and self.power - self.whole_power > self.part_margin

    def describe(self) -> str:
        return (f"a spectral line at {self.freq_hz:.4g} Hz {self.phrase} (normalised power {self.power:.0f} "
                f"there against {self.whole_power:.0f} over the whole record; score {self.score:.1f}, "
                f"threshold {self.threshold:.1f})")


def banded_line(ctx: Context, after: Fit, found: list[FoundEffect], drift: DriftLine | None = None
                ) -> tuple[list[FoundEffect], BandedLine | None]:
    """After the last refit: a line in part of the record, and the named effects it leaves.

    Returns the line only when it is present, only in part, and not a drifting line
    found by line_drift.py (``drift``) seen in one part: a drift whose frequencies
    cover the line and whose coherent power is at least the part's is the fuller
    account (a line drifting 0.15 %/°C showed as 24 in one quarter against 68 along
    its track). The converse happens too: an intermittent line can read as a spurious
    drift (a cooling-only line: −5.2 %/hour at power 28 against 46 in its part),
    and then this line is kept and said first. A named
    periodic_interference within two Fourier bins of it then has its probability
    multiplied by ``1 − real_probability(score, threshold)``.
    """
    resid = ctx.resid_full(after)
    spec = after.model.effect(PERIODIC)
    if spec is not None:
        resid = resid + sine_dph(spec["freq_hz"], spec["amplitude_dph"], ctx.log.t_s)
    log = ctx.log
    # a record over 2^20 samples: the window with the widest temperature span, as line_drift.py
    # (chosen from the temperature alone; 10 M samples took 13 s CPU whole, 27 FFTs of 10 M)
    cut = slice(*window(log.chamber_temp_c, len(resid)))
    line = banded_scan(high_passed(resid[cut], ctx.bins.samples_per_bin), ctx.fs_hz, ctx.noise,
                       0.5 / ctx.bins.width_s,
                       record_parts(log.table_rate_dps[cut], log.chamber_temp_c[cut], ctx.fs_hz))
    pulse = after.model.effect(QUANTIZATION)
    if line is None or not line.part_only or (pulse is not None and line_within_quantization(
            line.amplitude_dph, line.freq_hz, pulse["pulse_arcsec"])) or _drift_covers(ctx, drift, line):
        return found, None      # none, or the pulse counter's beat (bounded in angle), as periodic.py's search
    margin = 2.0 / (log.t_s[-1] - log.t_s[0])
    whole = 1.0 - real_probability(line.score, line.threshold)
    return [replace(f, probability=f.probability * whole)
            if f.name == PERIODIC and abs(f.parameters.get("freq_hz", math.nan) - line.freq_hz) <= margin
            else f for f in found], line


def _drift_covers(ctx: Context, drift: DriftLine | None, line: BandedLine) -> bool:
    """Whether the drifting line crosses the line's frequency (two bins' margin) with at least its power."""
    if drift is None or drift.power < line.power:
        return False
    freq_hz = line.freq_hz
    log = ctx.log
    temp = log.sensor_temp_c if log.sensor_temp_c is not None else log.chamber_temp_c
    x = np.asarray(temp if drift.covariate == "temperature" else log.t_s - log.t_s[0], dtype=float)
    lo, hi = drift.span_hz(x - float(np.mean(x)))
    margin = 2.0 / (log.t_s[-1] - log.t_s[0])
    return lo - margin <= freq_hz <= hi + margin


def high_passed(resid_dph: np.ndarray, per_bin: int) -> np.ndarray:
    """The residual less each bin's mean (a trailing part bin less its own mean)."""
    r = np.asarray(resid_dph, dtype=float).copy()
    body = (r.size // per_bin) * per_bin
    blocks = r[:body].reshape(-1, per_bin)
    r[:body] = (blocks - blocks.mean(axis=1, keepdims=True)).ravel()
    if body < r.size:
        r[body:] -= r[body:].mean()
    return r


def record_parts(rate_dps: np.ndarray, temp_c: np.ndarray, fs_hz: float) -> list[Part]:
    """The parts tried (see the module docstring); each holds at least ``MIN_PART_SHARE`` of the samples."""
    abs_rate = np.abs(np.asarray(rate_dps, dtype=float))
    temp = np.asarray(temp_c, dtype=float)
    parts: list[Part] = []
    moving = abs_rate > RATE_CHANGE_DPS
    if np.count_nonzero(moving) > 0:
        for q in RATE_QUANTILES:
            level = float(np.quantile(abs_rate[moving], q))
            parts.append(Part(f"rate_q{int(100 * q)}", (abs_rate >= level).astype(float),
                              f"only at |rate| ≥ {level:.3g} deg/s"))
        parts.append(Part("rate_weighted", abs_rate / float(np.max(abs_rate)), "with amplitude ∝ |rate|"))
        parts.append(Part("at_rest", (~moving).astype(float), "only while the table is at rest"))
    if np.ptp(temp) > 2.0:
        median = float(np.median(temp))
        parts.append(Part("cold", (temp < median).astype(float), f"only below {median:.3g} °C"))
        parts.append(Part("warm", (temp >= median).astype(float), f"only at or above {median:.3g} °C"))
        span = max(1, int(TEMP_RATE_SPAN_S * fs_hz))
        slope = (temp[np.minimum(np.arange(temp.size) + span, temp.size - 1)]
                 - temp[np.maximum(np.arange(temp.size) - span, 0)]) / (2.0 * span / fs_hz / 60.0)
        parts.append(Part("heating", (slope > TEMP_RATE_C_PER_MIN).astype(float), "only while heating"))
        parts.append(Part("cooling", (slope < -TEMP_RATE_C_PER_MIN).astype(float), "only while cooling"))
    quarter = np.minimum(4 * np.arange(temp.size) // max(temp.size, 1), 3)
    names = ("first", "second", "third", "last")
    parts += [Part(f"time_{i}", (quarter == i).astype(float), f"only in the {names[i]} quarter of the record")
              for i in range(4)]
    return [p for p in parts if np.mean(p.weight > 0) >= MIN_PART_SHARE and np.mean(p.weight > 0) < 0.999]


def banded_scan(resid_dph: np.ndarray, fs_hz: float, noise: NoiseModel, f_lo_hz: float,
                parts: list[Part]) -> BandedLine | None:
    """The strongest normalised line over ``parts`` from ``f_lo_hz`` to Nyquist (None: no band or part)."""
    r = np.asarray(resid_dph, dtype=float)
    n = r.size
    f = sp_fft.rfftfreq(n, 1.0 / fs_hz)
    band = (f >= f_lo_hz) & (f < 0.5 * fs_hz * 0.999)
    if np.count_nonzero(band) < _MIN_BAND_BINS or not parts:
        return None
    psd = noise.psd_two_sided(f[band], fs_hz)
    whole_power = np.abs(sp_fft.rfft(r, workers=1)[band]) ** 2 / (n * fs_hz)
    psd = psd * _shape(whole_power / psd, f[band])
    best: tuple[float, int, Part, float] | None = None
    for part in parts:
        ratio, level = _normalised((r * part.weight).astype(np.float32), part.weight, fs_hz, psd, band)
        k = int(np.argmax(ratio))
        if best is None or ratio[k] > best[0]:
            best = (float(ratio[k]), k, part, level)
    assert best is not None
    power, k, part, level = best
    whole = whole_power / psd    # C = 0 at every whole-record bin inside (0, fs/2)
    whole = whole / max(float(np.median(whole)) / math.log(2.0), MIN_LEVEL)
    # a sine A·w(t) puts |Σ w·r·e|² = (A·Σw²/2)² at its frequency: A from the normalised power
    sum_w2 = float(part.weight @ part.weight)
    amplitude = 2.0 * math.sqrt(power * level * fs_hz * float(psd[k]) / sum_w2)
    return BandedLine(part.key, part.phrase, float(f[band][k]), power, amplitude, float(whole[k]),
                      float(len(parts) * np.count_nonzero(band)), len(parts))


def _shape(ratio: np.ndarray, f_hz: np.ndarray) -> np.ndarray:
    """The whole record's periodogram over the noise PSD, smoothed along frequency: the model PSD's shape error.

    The threshold sits near 17–19 Exp(1) units, where a level a few per cent off
    multiplies the tail: e^(s·δ), 2.3-fold for δ = 5 %. The noise model's PSD is
    known to that (on P1 the ratio's block medians ran 0.86–1.07 across the band),
    and the shape error is common to every part, so it is read once from the whole
    record: the log of ``SHAPE_BLOCKS`` block medians, a quadratic in frequency.
    """
    blocks = min(SHAPE_BLOCKS, ratio.size // 64)
    if blocks < 4:
        return np.ones_like(ratio)
    size = ratio.size // blocks
    medians = np.median(ratio[: blocks * size].reshape(blocks, size), axis=1) / math.log(2.0)
    centres = f_hz[: blocks * size].reshape(blocks, size).mean(axis=1)
    coef = np.polyfit(centres, np.log(np.maximum(medians, 1e-12)), 2)
    return np.exp(np.polyval(coef, f_hz))


def _normalised(x: np.ndarray, weight: np.ndarray, fs_hz: float, psd: np.ndarray, band: np.ndarray
                ) -> tuple[np.ndarray, float]:
    """½χ² of a sine at each band bin of the weighted record ``x`` = w·r, re-levelled by its median, and the level.

    Weighted white noise is not circular: its Fourier sum X has real and imaginary
    parts of unequal variance where C = Σw²·e^(−4πifk/fs) is not small against
    S = Σw² (a part with many edges, at the low end of the band), and |X|²/S
    then has a tail like χ²₁'s, far heavier than Exp(1) (the plain ratio fired on
    6 of 400 effect-free draws at a 0.5 % bound). With that 2×2 covariance,
    ½χ² = (S·|X|² − Re(C̄·X²)) / (σ²·(S² − |C|²)), Exp(1) under noise exactly.

    The level is not taken below ``MIN_LEVEL`` of the noise model's: a part where the
    output holds still (a dead zone at rest) has almost no noise, and its tiny median
    would blow any leftover of the model's own slow terms up into a "line".
    """
    # single precision: half the CPU of the 2 FFTs per part (0.53 → 0.3 s on P2), errors ~1e-6 of a bin
    spectrum = sp_fft.rfft(x, workers=1)
    k = np.flatnonzero(band)
    big_x = spectrum[k].astype(complex)
    w2 = weight * weight
    s_w2 = float(np.sum(w2))
    squared = sp_fft.rfft(w2.astype(np.float32), workers=1)
    m = 2 * k
    c = np.where(m <= x.size // 2, squared[np.minimum(m, squared.size - 1)],
                 np.conj(squared[np.clip(x.size - m, 0, squared.size - 1)]))
    det = np.maximum(s_w2 * s_w2 - np.abs(c) ** 2, 1e-6 * s_w2 * s_w2)
    power = (s_w2 * np.abs(big_x) ** 2 - (np.conj(c) * big_x * big_x).real) / (det * fs_hz * psd)
    level = max(float(np.median(power)) / math.log(2.0), MIN_LEVEL)
    return power / level, level
