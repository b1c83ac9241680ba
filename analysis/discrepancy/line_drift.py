"""A periodic line whose frequency drifts with temperature or time: found, and told from a fixed line.

The catalogue's periodic_interference (periodic.py) looks for one fixed line
in the full-rate spectrum of the whole record. A line whose frequency moves
(a vibration mode, a dither or a clock drifting with the unit's temperature)
smears over as many Fourier bins as it moves: on the held-out set a periodic
term drifting 0.1 %/°C, sized 10σ by its norm against the white noise, was
called unexplained in 0 of 9 runs and nothing was said about it.

Two stages:

1. Where (line_ridge.py): the best ridge through the short-time spectra of the
   residual, a track f_ref + slope·(x − x̄) per covariate x (temperature, time).
2. How strong (here): the coherent power of a line whose phase follows the
   track, 2π·f·(τ + c·D(τ)) with D(τ) = ∫(x − x̄)dτ (instantaneous frequency
   f·(1 + c·(x − x̄)), c the relative drift per unit), searched on a grid of c
   around the ridge's slope (a quarter cycle of phase apart over the record)
   and of f around its frequency. Divided by the noise PSD, the power of any
   one (f, c) is Exp(1) under noise, so a 10σ line (‖s‖/σ = 10) has power 50
   where the ridge alone collects about 25 against a noise ridge of 30.

(a) Whether there is a line: its power against the maximum of Exp(1) over
every (f, c) cell of the *whole* search space (each frequency bin to Nyquist,
twice refined, × every c to ±``C_MAX`` at the Nyquist frequency's quarter-cycle
step, for each covariate). The cells searched are a subset of those, chosen by
the ridge, so the union bound holds whatever the ridge picked; the threshold
is ``DETECT_ALPHA`` = 0.5 %, what this test may add to the false alarms.
(b) Whether its frequency moves: the drifting track must beat the best fixed
frequency over every frequency the track crosses by the union bound over the
c values tried at ``DRIFT_ALPHA`` (a fixed line puts all its power at c = 0).
With which covariate: the one whose track has the larger power; when the
other is within ``SAME_POWER`` the record cannot tell them apart and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrocal.analysis.discrepancy.candidates import PERIODIC
from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.line_ridge import RidgeTrack, best_ridges
from gyrocal.analysis.discrepancy.lookalikes import real_probability
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.periodic import max_exponential_score, sine_dph
from gyrocal.analysis.discrepancy.result import FoundEffect
from gyrocal.analysis.discrepancy.scoring import Fit

#: Largest relative drift searched, per unit of the covariate (1 %/degC; 1 % per hour).
C_MAX = {"temperature": 0.01, "time": 0.01 / 3600.0}
#: (display unit, covariate units per display unit)
UNITS = {"temperature": ("°C", 1.0), "time": ("hour", 3600.0)}
#: False alarms the detection adds at most (union bound over the whole search space).
DETECT_ALPHA = 0.005
#: Level of the drift test (a fixed line called drifting).
DRIFT_ALPHA = 0.005
#: Powers (Exp(1) units) closer than this: the two covariates explain the line alike.
SAME_POWER = 3.0
#: Most samples the test reads (a window of a longer record: ``window``).
MAX_SAMPLES = 1 << 20
#: Frequency refinement of the coherent spectra (zero padding).
_PAD = 2
#: Most drift values tried around the ridge's slope, and how many go through one FFT.
_MAX_DRIFTS = 129
_CHUNK = 32


@dataclass(frozen=True)
class DriftLine:
    """The strongest line track and both tests' figures."""

    covariate: str            # "temperature" or "time"
    freq_hz: float            # at the covariate's mean
    drift_per_unit: float     # relative frequency change per degC, or per second
    power: float              # coherent power along the drifting track (Exp(1) units)
    fixed_power: float        # best fixed-frequency power over the frequencies the track crosses
    n_cells: float            # (f, c) cells of the whole search space (the union bound's count)
    n_drifts: int             # c values tried around the ridge's slope
    other_power: float        # the other covariate's best track (nan if not searched)

    @property
    def score(self) -> float:
        return max_exponential_score(self.power, self.n_cells)

    @property
    def threshold(self) -> float:
        return -math.log10(DETECT_ALPHA)

    @property
    def present(self) -> bool:
        return self.score > self.threshold

    @property
    def drift_margin(self) -> float:
        return math.log(max(self.n_drifts, 1) / DRIFT_ALPHA)

    @property
    def drifting(self) -> bool:
        return self.present and self.power - self.fixed_power > self.drift_margin

    @property
    def drift_per_display_unit(self) -> float:
        return self.drift_per_unit * UNITS[self.covariate][1]

    def describe(self) -> str:
        unit = UNITS[self.covariate][0]
        text = (f"a periodic line near {self.freq_hz:.4g} Hz whose frequency moves "
                f"{100 * self.drift_per_display_unit:+.2g} %/{unit} with {self.covariate} (coherent power "
                f"{self.power:.0f} along the drifting track against {self.fixed_power:.0f} at the best fixed "
                f"frequency; score {self.score:.1f}, threshold {self.threshold:.1f})")
        other = "time" if self.covariate == "temperature" else "temperature"
        if math.isfinite(self.other_power) and self.power - self.other_power < SAME_POWER:
            text += f"; a drift with {other} fits it about as well"
        return text

    def span_hz(self, x_dev: np.ndarray) -> tuple[float, float]:
        """The frequencies the line passes through for the covariate's deviations ``x_dev``."""
        f = self.freq_hz * (1.0 + self.drift_per_unit * np.asarray(x_dev))
        return float(np.min(f)), float(np.max(f))


def drifting_line(ctx: Context, after: Fit, found: list[FoundEffect]
                  ) -> tuple[list[FoundEffect], DriftLine | None]:
    """After the last refit: a drifting line in the residual, and the named effects it leaves.

    A named periodic_interference is put back first (it may be the fixed line
    nearest a drifting one, fitted to part of it); the drifting reading is tested
    against the fixed one on the record as measured. When the line drifts, a named
    periodic_interference within the frequencies it crosses keeps only the
    probability that it is the whole account, ``1 − real_probability(score,
    threshold)``, the adequacy test's odds rule (adequacy.py). Returns the drift
    only when it is present and drifting.
    """
    resid = ctx.resid_full(after)
    line_spec = after.model.effect(PERIODIC)
    if line_spec is not None:
        resid = resid + sine_dph(line_spec["freq_hz"], line_spec["amplitude_dph"], ctx.log.t_s)
    log = ctx.log
    temp = log.sensor_temp_c if log.sensor_temp_c is not None else log.chamber_temp_c
    covariates = {"temperature": np.asarray(temp, dtype=float), "time": log.t_s - log.t_s[0]}
    drift = drift_scan(resid, ctx.fs_hz, ctx.noise, 0.5 / ctx.bins.width_s, covariates)
    if drift is None or not drift.drifting:
        return found, None
    lo, hi = drift.span_hz(covariates[drift.covariate] - float(np.mean(covariates[drift.covariate])))
    margin = 2.0 / (log.t_s[-1] - log.t_s[0])
    whole = 1.0 - real_probability(drift.score, drift.threshold)
    return [replace(f, probability=f.probability * whole)
            if f.name == PERIODIC and lo - margin <= f.parameters.get("freq_hz", math.nan) <= hi + margin
            else f for f in found], drift


def drift_scan(resid_dph: np.ndarray, fs_hz: float, noise: NoiseModel, f_lo_hz: float,
               covariates: dict[str, np.ndarray]) -> DriftLine | None:
    """The strongest drifting-line track of the residual (None: no band or covariate to search).

    ``covariates`` maps "temperature" (degC) and "time" (s) to per-sample values. A record
    longer than ``MAX_SAMPLES`` is judged on its window of that many samples with the widest
    temperature span (``window``).
    """
    start, stop = window(covariates.get("temperature"), len(resid_dph))
    covariates = {name: np.asarray(values, dtype=float)[start:stop] for name, values in covariates.items()}
    r = np.asarray(resid_dph, dtype=float)[start:stop]
    r = r - float(np.mean(r))
    tracks = best_ridges(r, fs_hz, noise, f_lo_hz, covariates, covariates.get("temperature"))
    if not tracks:
        return None
    spectrum = np.fft.rfft(r)
    n_freqs = _PAD * (0.5 * fs_hz - f_lo_hz) * r.size / fs_hz
    n_cells, best = 0.0, {}
    for name in {track.covariate for track in tracks}:
        dev = covariates[name] - float(np.mean(covariates[name]))
        path = _Path(dev, np.cumsum(dev) / fs_hz, fs_hz)
        n_cells += n_freqs * (2.0 * C_MAX[name] * 0.5 * fs_hz * 4.0 * path.nonlinear + 1.0)
        lines = [_follow_up(spectrum, r.size, noise, track, path) for track in tracks if track.covariate == name]
        best[name] = max(lines, key=lambda line: line.power)
    top = max(best.values(), key=lambda line: line.power)
    others = [line.power for line in best.values() if line is not top]
    return replace(top, n_cells=n_cells, other_power=others[0] if others else math.nan)


def window(temp_c: np.ndarray | None, n: int) -> tuple[int, int]:
    """(start, stop) of the ``MAX_SAMPLES`` samples with the widest temperature span (all if fewer).

    Chosen from the temperature alone, never from the residual, so the union
    bound holds on the window as on a record of its length. The cost of the test
    grows with the samples (an overnight 10 M-sample log took 15 s CPU); the window
    holds it at that of the 2.6-hour, 100 Hz validation profile.
    """
    if n <= MAX_SAMPLES:
        return 0, n
    starts = np.linspace(0, n - MAX_SAMPLES, 64).astype(int)
    if temp_c is None:
        start = int(starts[len(starts) // 2])
    else:
        step = max(1, n // 100_000)
        coarse = np.asarray(temp_c, dtype=float)[::step]
        span = [np.ptp(coarse[a // step:(a + MAX_SAMPLES) // step]) for a in starts]
        start = int(starts[int(np.argmax(span))])
    return start, start + MAX_SAMPLES


@dataclass(frozen=True)
class _Path:
    """A covariate's deviation from its mean and its running integral D(τ), per sample."""

    dev: np.ndarray
    integral: np.ndarray
    fs_hz: float

    @property
    def nonlinear(self) -> float:
        """Peak-to-peak of D(τ) less its best straight line (a linear part only shifts the frequency)."""
        step = max(1, self.integral.size // 20000)
        d = self.integral[::step]
        u = np.arange(d.size, dtype=float)
        return float(np.ptp(d - np.polyval(np.polyfit(u, d, 1), u)))

    def integral_at(self, n_points: int) -> np.ndarray:
        """D at ``n_points`` evenly spaced times over the record (the baseband's sample times)."""
        t = np.arange(n_points) * (self.integral.size / n_points)
        return np.interp(t, np.arange(self.integral.size), self.integral)


def _follow_up(spectrum: np.ndarray, n: int, noise: NoiseModel, track: RidgeTrack, path: _Path) -> DriftLine:
    """Coherent power on a (c, f) grid around the ridge's track, and the best fixed line near it.

    The record's spectrum within the band the line can cross is brought down to
    baseband and back to time (a band-limited copy of the record at a few
    points per cycle of the band, exact for a line inside it), where each trial
    c costs one short FFT instead of a pass over every sample.
    """
    fs_hz = path.fs_hz
    k0 = int(round(track.freq_hz * n / fs_hz))
    f0 = k0 * fs_hz / n
    c_max = C_MAX[track.covariate]
    c1 = float(np.clip(track.slope_hz_per_unit / f0, -c_max, c_max))
    c_half = track.slope_resolution / f0
    step = 1.0 / (4.0 * f0 * max(path.nonlinear, 1e-12))
    n_c = int(min(_MAX_DRIFTS, 2 * math.ceil(c_half / step) + 1))
    drifts = c1 + np.linspace(-c_half, c_half, n_c) if n_c > 1 else np.array([c1])
    spread = float(np.max(np.abs(path.dev)))
    fixed_span = abs(c1) * f0 * spread + track.freq_resolution_hz
    half_bins = int(math.ceil((fixed_span + c_half * f0 * spread) * n / fs_hz)) + 2
    points = 1 << int(math.ceil(math.log2(2 * half_bins + 16)))
    placed = np.zeros(points, dtype=complex)
    lo, hi = max(k0 - half_bins, 1), min(k0 + half_bins + 1, spectrum.size)
    placed[np.arange(lo - k0, hi - k0) % points] = spectrum[lo:hi]
    base = np.fft.ifft(placed) * points          # Σ over the band of X_k e^(2πi(k−k0)m/points)
    d = path.integral_at(points)
    # Σ over samples ≈ (n/points)·Σ over the points of base/n; over the noise's n·fs·PSD: Exp(1)
    norm = points * points * n * fs_hz * float(noise.psd_two_sided(np.array([f0]), fs_hz)[0]) * track.level
    width = track.freq_resolution_hz + c_half * f0 * spread
    power, freq, drift = _grid(base, d, f0, drifts, width, n / fs_hz)
    coarse = float(drifts[1] - drifts[0]) if n_c > 1 else 0.0
    if coarse > 1.5 * step:   # the grid was capped: refine around its best at the quarter-cycle step
        fine = drift + np.linspace(-coarse, coarse, int(min(_MAX_DRIFTS, 2 * math.ceil(coarse / step) + 1)))
        power, freq, drift = max((power, freq, drift), _grid(base, d, f0, fine, width, n / fs_hz))
        n_c += fine.size
    fixed, _, _ = _grid(base, d, f0, np.zeros(1), fixed_span, n / fs_hz)
    return DriftLine(track.covariate, f0 + freq, drift, power / norm, fixed / norm, 0.0, n_c, math.nan)


def _grid(base: np.ndarray, d: np.ndarray, f0: float, drifts: np.ndarray, width_hz: float,
          duration_s: float) -> tuple[float, float, float]:
    """max over c and |δf| ≤ width of |Σ_m base_m·e^(−2πi(f0·c·D_m + δf·τ_m))|²: (power, δf, c)."""
    points = base.size
    offsets = np.fft.fftfreq(_PAD * points, duration_s / points)
    keep = np.abs(offsets) <= width_hz
    best = (-1.0, 0.0, 0.0)
    for start in range(0, drifts.size, _CHUNK):
        part = drifts[start:start + _CHUNK]
        rows = base[None, :] * np.exp(-2j * math.pi * f0 * part[:, None] * d[None, :])
        power = np.abs(np.fft.fft(rows, _PAD * points, axis=1)[:, keep]) ** 2
        i, j = np.unravel_index(int(np.argmax(power)), power.shape)
        if power[i, j] > best[0]:
            best = (float(power[i, j]), float(offsets[keep][j]), float(part[i]))
    return best
