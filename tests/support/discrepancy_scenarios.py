"""Measured logs with a known truth: procedure-like inputs, a nominal model, hidden effects.

The discrepancy workflow is only trustworthy if it names the effect that is
really there, at sizes near the noise, and nothing when nothing is there.
This module makes such data with the project's own simulator: a schedule of
chamber temperature (soaks at several setpoints joined by ramps of different
rates, so lag and rate effects can be told apart) and table rate (static
holds, ± dwells at several rates, a slow full revolution so table-angle
effects show), and a model = nominal + hidden effect(s) whose base numbers
are also off (bias, SF, tempcos), so the workflow must refit before it looks.

Sizes are given as the SNR the hidden effect would have if its shape were
known: the amplitude for which the whitened, base-projected signature has
norm ``snr`` (its expected χ² gain is snr²). For shape-only effects
(thermal_lag) the τ is solved for instead; dead_zone is sized by which rate
levels its threshold swallows; markov_bias by its σ.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gyrocal.analysis.discrepancy.context import Context
from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.scoring import Fit, Whitener, gls_fit
from gyrocal.analysis.discrepancy.segments import make_bins
from gyrocal.analysis.discrepancy.signatures import DesignBuilder, placeholder_spec
from gyrocal.models.gyro_model import EffectSpec, GyroModel, parse_model
from gyrocal.models.gyro_sim import GyroSamples, simulate
from gyrocal.models.indicated import ModelInputs
from gyrocal.models.rate_units import dph_to_output


@dataclass(frozen=True)
class Profile:
    """Inputs of one simulated procedure."""

    t_s: np.ndarray
    table_rate_dps: np.ndarray
    chamber_temp_c: np.ndarray

    @property
    def fs_hz(self) -> float:
        return 1.0 / float(self.t_s[1] - self.t_s[0])

    @property
    def inputs(self) -> ModelInputs:
        return ModelInputs.of(self.t_s, self.table_rate_dps, self.chamber_temp_c)


def procedure_profile(duration_s: float = 3600.0, fs_hz: float = 10.0,
                      setpoints_c: tuple[float, ...] = (25.0, 40.0, 10.0, 25.0),
                      ramps_c_per_min: tuple[float, ...] = (3.0, 5.0, 2.0),
                      rates_dps: tuple[float, ...] = (0.5, 2.0, 10.0, 50.0, 200.0),
                      dwell_s: float = 20.0, static_s: float = 120.0,
                      slow_rate_dps: float = 3.0, allan_hold_s: float = 0.0,
                      accel_dps2: float | None = None) -> Profile:
    """Soaks at ``setpoints_c`` joined by ramps; in each soak a static hold, ± dwells, one slow turn.

    ``allan_hold_s`` adds a long static hold at the end of the first soak (a
    procedure's Allan hold). ``accel_dps2`` gives the table a real acceleration:
    each rate change becomes a slew at that rate of change, eating into the
    start of the new dwell (None: instantaneous steps, as a table logged at a
    low rate would show them).
    """
    if len(ramps_c_per_min) != len(setpoints_c) - 1:
        raise ValueError("one ramp rate per transition between setpoints is needed")
    ramp_s = [abs(b - a) / r * 60.0 for a, b, r in
              zip(setpoints_c[:-1], setpoints_c[1:], ramps_c_per_min, strict=True)]
    soak_s = (duration_s - sum(ramp_s) - allan_hold_s) / len(setpoints_c)
    table_s = static_s + 2 * dwell_s * len(rates_dps) + 360.0 / slow_rate_dps
    if soak_s < table_s:
        raise ValueError(f"soaks of {soak_s:.0f} s cannot hold the {table_s:.0f} s of table tests")
    pieces: list[tuple[float, float, float, float]] = []   # duration, rate, T start, T end
    for i, setpoint in enumerate(setpoints_c):
        if i > 0:
            pieces.append((ramp_s[i - 1], 0.0, setpoints_c[i - 1], setpoint))
        used = 0.0
        pieces.append((static_s, 0.0, setpoint, setpoint))
        used += static_s
        for rate in rates_dps:
            pieces.append((dwell_s, rate, setpoint, setpoint))
            pieces.append((dwell_s, -rate, setpoint, setpoint))
            used += 2 * dwell_s
        pieces.append((360.0 / slow_rate_dps, slow_rate_dps, setpoint, setpoint))
        used += 360.0 / slow_rate_dps
        pieces.append((soak_s - used + (allan_hold_s if i == 0 else 0.0), 0.0, setpoint, setpoint))
    n = int(round(duration_s * fs_hz))
    t = np.arange(n) / fs_hz
    rate = np.zeros(n)
    temp = np.zeros(n)
    start = 0.0
    for length, r, t0, t1 in pieces:
        sel = (t >= start) & (t < start + length)
        rate[sel] = r
        temp[sel] = t0 + (t1 - t0) * (t[sel] - start) / length
        start += length
    temp[t >= start] = setpoints_c[-1]
    if accel_dps2 is not None:
        rate = _slewed(rate, fs_hz, accel_dps2)
    return Profile(t, rate, temp)


def _slewed(rate_dps: np.ndarray, fs_hz: float, accel_dps2: float) -> np.ndarray:
    """Each step of the commanded rate replaced by a constant-acceleration slew."""
    out = rate_dps.copy()
    for i in np.flatnonzero(np.diff(rate_dps)) + 1:
        start, target = out[i - 1], rate_dps[i]
        steps = int(math.ceil(abs(target - start) / accel_dps2 * fs_hz))
        k = np.arange(1, steps + 1)
        ramp = start + np.sign(target - start) * np.minimum(k * accel_dps2 / fs_hz, abs(target - start))
        stop = min(i + steps, out.size)
        out[i:stop] = ramp[: stop - i]
    return out


def five_temperature_profile(fs_hz: float = 100.0, accel_dps2: float = 10.0) -> Profile:
    """The second validation profile: five temperatures, a heating and a cooling branch.

    25 → 55 °C (heating), then 40, 10 and −10 °C (cooling), ramps of 2, 1, 3
    and 1.5 °C/min, a 30-minute static hold in the first soak, 100 Hz, a table
    accelerating at 10 deg/s²: 2.6 hours, nothing in common with the first
    profile but the kind of steps.
    """
    return procedure_profile(9300.0, fs_hz, setpoints_c=(25.0, 55.0, 40.0, 10.0, -10.0),
                             ramps_c_per_min=(2.0, 1.0, 3.0, 1.5),
                             rates_dps=(1.0, 4.0, 20.0, 100.0), dwell_s=30.0, static_s=90.0,
                             slow_rate_dps=4.0, allan_hold_s=1800.0, accel_dps2=accel_dps2)


def static_profile(duration_s: float = 7200.0, fs_hz: float = 200.0, temp_c: float = 25.0) -> Profile:
    """A long static at one temperature (the third validation profile: 2 h at 200 Hz).

    Only what shows without rate or temperature change can be named here: bias
    drifts, interference, quantization, the Markov bias; the table and
    temperature effects have nothing to act on.
    """
    t = np.arange(int(round(duration_s * fs_hz))) / fs_hz
    return Profile(t, np.zeros_like(t), np.full_like(t, temp_c))


NOMINAL = {
    "version": 1, "name": "nominal FOG (discrepancy scenarios)", "output_units": "deg/s",
    "scale_factor": 1.0, "reference_temp_c": 25.0, "bias_dph": 2.0,
    "bias_tempco_dph_per_c": 0.03, "sf_error_ppm": 50.0, "sf_tempco_ppm_per_c": 20.0,
    "earth_rate_dph": 11.6,
    "noise": {"arw_deg_per_rth": 0.01, "bias_instability_dph": 0.03},
}

#: Shape parameters of hidden effects when a test does not choose them.
DEFAULT_SHAPES: dict[str, dict[str, float]] = {
    "warmup_transient": {"tau_s": 400.0},
    "table_angle_harmonic": {"phase_deg": 40.0},
    "periodic_interference": {"freq_hz": 1.37},
    "markov_bias": {"tau_s": 30.0},
}


def nominal_model() -> GyroModel:
    return parse_model(NOMINAL, "scenarios.NOMINAL")


def true_base(nominal: GyroModel) -> GyroModel:
    """The unit's real base numbers: off from the nominal model, as a real unit is."""
    return replace(nominal, bias_dph=nominal.bias_dph + 0.4,
                   bias_tempco_dph_per_c=nominal.bias_tempco_dph_per_c * 1.3,
                   sf_error_ppm=nominal.sf_error_ppm + 15.0,
                   sf_tempco_ppm_per_c=nominal.sf_tempco_ppm_per_c * 0.8)


def _snr_tools(nominal: GyroModel, profile: Profile, noise: NoiseModel, max_bins: int):
    bins = make_bins(profile.t_s, profile.fs_hz, max_bins=max_bins)
    builder = DesignBuilder(profile.inputs, bins)
    cov = noise.bin_covariance(bins.centre_s, bins.width_s, bins.samples_per_bin, profile.fs_hz)
    return bins, builder, Whitener(cov)


def pair_separation(profile: Profile, pair: tuple[str, str], snr: float, max_bins: int,
                    nominal: GyroModel | None = None) -> float:
    """Whitened distance between two effects' signatures at ``snr`` once the other is fitted.

    With the nominal model's true noise: the design separation d of the pair on ``profile``, so
    the best any rule can do naming the right one first is Φ(d/2).
    """
    nominal = nominal or nominal_model()
    base = true_base(nominal)
    bins, builder, whitener = _snr_tools(nominal, profile, NoiseModel.of_model(nominal), max_bins)
    fit = gls_fit(builder, whitener, bins.mean(builder.rate_dph(base)), base)
    unit = []
    for name in pair:
        _, x = builder.extra_columns(base, placeholder_spec(name, {}))
        w = whitener.white(x[:, 0])
        w = w - fit.basis @ (fit.basis.T @ w)
        unit.append(w / np.linalg.norm(w))
    return snr * math.sqrt(max(0.0, 1.0 - float(unit[0] @ unit[1]) ** 2))


def sized_effect(name: str, snr: float, profile: Profile, nominal: GyroModel | None = None,
                 shape: dict[str, float] | None = None, max_bins: int = 2000) -> EffectSpec:
    """The effect at the amplitude (or τ) whose known-shape detection SNR is ``snr``.

    ``max_bins`` should match the analysis (the SNR is that of the bin means).
    """
    nominal = nominal or nominal_model()
    shape = dict(DEFAULT_SHAPES.get(name, {}) if shape is None else shape)
    if name in ("dead_zone", "markov_bias", "quantization"):
        raise ValueError(f"{name} is sized by its own parameters, not by an SNR; build its EffectSpec")
    noise = NoiseModel.of_model(nominal)
    base = true_base(nominal)
    if name == "periodic_interference":
        sigma = noise.white_sigma_dph(profile.fs_hz)
        amplitude = snr * sigma * math.sqrt(2.0 / len(profile.t_s))
        return EffectSpec(name, {"freq_hz": shape["freq_hz"], "amplitude_dph": amplitude})
    bins, builder, whitener = _snr_tools(nominal, profile, noise, max_bins)
    if name == "thermal_lag":
        return EffectSpec(name, {"tau_s": _lag_for_snr(snr, base, builder, whitener, bins)})
    spec = placeholder_spec(name, shape)
    fit = gls_fit(builder, whitener, builder.bins.mean(builder.rate_dph(base)), base)
    columns, x = builder.extra_columns(base, spec)
    wc = whitener.white(x)
    perp = wc - fit.basis @ (fit.basis.T @ wc)
    if name == "table_angle_harmonic":
        phase = math.radians(shape["phase_deg"])
        norm = float(np.linalg.norm(perp @ np.array([math.cos(phase), math.sin(phase)])))
        return EffectSpec(name, {"amplitude_dph": snr / norm, "phase_deg": shape["phase_deg"]})
    norm = float(np.linalg.norm(perp[:, 0]))
    params = dict(spec.params)
    params[columns[0].key] = snr / norm
    return EffectSpec(name, params)


def sized_extra(shape_dph: np.ndarray, snr: float, profile: Profile, nominal: GyroModel | None = None,
                max_bins: int = 2000) -> np.ndarray:
    """Structure outside the catalogue (a per-sample shape, deg/h) scaled to known-shape SNR ``snr``.

    The counterpart of ``sized_effect`` for shapes the catalogue does not have: the
    scale for which the whitened, base-projected binned shape has norm ``snr``.
    """
    nominal = nominal or nominal_model()
    bins, builder, whitener = _snr_tools(nominal, profile, NoiseModel.of_model(nominal), max_bins)
    fit = gls_fit(builder, whitener, bins.mean(builder.rate_dph(true_base(nominal))), true_base(nominal))
    wc = whitener.white(bins.mean(shape_dph))
    norm = float(np.linalg.norm(wc - fit.basis @ (fit.basis.T @ wc)))
    if not norm > 0:
        raise ValueError("the shape is all explained by the base (bias, tempco, SF): it has no SNR")
    return shape_dph * (snr / norm)


def sized_markov(snr: float, tau_s: float, profile: Profile, nominal: GyroModel | None = None
                 ) -> EffectSpec:
    """markov_bias of correlation time ``tau_s`` whose expected likelihood ratio is snr².

    The stochastic counterpart of ``sized_effect``: E[LR] = 2·KL between the
    noise model with and without the process (Whittle form, on the test's
    one-second bins), solved for σ by bisection in log σ.
    """
    from gyrocal.analysis.discrepancy.stochastic import WhittleTest, fine_bins

    nominal = nominal or nominal_model()
    bins = fine_bins(profile.t_s, profile.fs_hz)
    test = WhittleTest(NoiseModel.of_model(nominal), bins, profile.fs_hz)
    lo, hi = math.log(1e-4), math.log(1e3)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if test.expected_lr(math.exp(mid), tau_s) < snr * snr:
            lo = mid
        else:
            hi = mid
    return EffectSpec("markov_bias", {"sigma_dph": math.exp(0.5 * (lo + hi)), "tau_s": tau_s})


def _lag_for_snr(snr: float, base: GyroModel, builder: DesignBuilder, whitener: Whitener, bins) -> float:
    """τ of thermal_lag whose noise-free misfit under the lag-free base is snr² (bisection in log τ)."""
    def misfit(tau_s: float) -> float:
        truth = base.with_effect(EffectSpec("thermal_lag", {"tau_s": tau_s}))
        y = bins.mean(builder.rate_dph(truth))
        return math.sqrt(gls_fit(builder, whitener, y, base).chi2)

    lo, hi = math.log(1.0), math.log(3000.0)
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        if misfit(math.exp(mid)) < snr:
            lo = mid
        else:
            hi = mid
    return math.exp(0.5 * (lo + hi))


def simulate_log(profile: Profile, hidden: list[EffectSpec], seed: int,
                 nominal: GyroModel | None = None, base_offset: bool = True,
                 extra_dph: np.ndarray | None = None) -> GyroSamples:
    """Simulated measured data: true base (or nominal) + hidden effects + the model's noise.

    ``extra_dph`` adds structure outside the catalogue (e.g. a bias step), in deg/h.
    """
    nominal = nominal or nominal_model()
    truth = true_base(nominal) if base_offset else nominal
    for spec in hidden:
        truth = truth.with_effect(spec)
    samples = simulate(truth, profile.t_s, profile.table_rate_dps, profile.chamber_temp_c, seed=seed)
    if extra_dph is not None:
        samples = replace(samples, gyro=samples.gyro + dph_to_output(extra_dph, truth.scale_factor))
    return samples


def write_log(samples: GyroSamples, path: str | Path, with_measured_extras: bool = False) -> Path:
    """A measured log (CSV or Parquet by suffix) with the spec's columns."""
    path = Path(path)
    columns = samples.log_columns()
    if not with_measured_extras:
        columns = {k: v for k, v in columns.items() if k not in ("sensor_temp_c", "table_angle_deg")}
    if path.suffix.lower() in (".parquet", ".pq"):
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(columns), path)
    else:
        header = ",".join(columns)
        np.savetxt(path, np.column_stack(list(columns.values())), delimiter=",", header=header,
                   comments="", fmt="%.10g")
    return path


def as_measured_log(samples: GyroSamples, source: str = "simulated"):
    """The simulated samples as the workflow's MeasuredLog (without the optional columns)."""
    from gyrocal.analysis.measured_log import MeasuredLog

    return MeasuredLog(source, samples.t_s, samples.table_rate_dps, samples.chamber_temp_c,
                       samples.gyro)


def analyse_scenario(profile: Profile, hidden: list[EffectSpec], seed: int, max_bins: int = 1000,
                     n_null: int = 300, extra_dph: np.ndarray | None = None):
    """Simulate a log with ``hidden`` effects and run the workflow against the nominal model."""
    from gyrocal.analysis.discrepancy.workflow import analyse

    samples = simulate_log(profile, hidden, seed, extra_dph=extra_dph)
    return analyse(nominal_model(), as_measured_log(samples), seed=seed, n_null=n_null,
                   max_bins=max_bins)


def base_refit(prof: Profile, seed: int, hidden: list[EffectSpec] | None = None,
               extra_dph: np.ndarray | None = None, *, model: GyroModel | None = None,
               max_bins: int = 1000) -> tuple[Context, Fit]:
    """A simulated log of ``prof`` (``hidden`` effects plus ``extra_dph``) and ``model`` (the
    nominal one by default) refitted to it with the model's noise, as the workflow's last refit
    leaves a record where nothing more is named: what a residual test is judged on by itself
    (tests and benchmarks of the noise-level and spike tests). Returns (context, fit)."""
    log = as_measured_log(simulate_log(prof, list(hidden or []), seed, extra_dph=extra_dph))
    model = nominal_model() if model is None else model
    ctx = Context(model, log, seed, 300, max_bins)
    ctx.use_noise(NoiseModel.of_model(model))
    return ctx, ctx.fit(model)


def timed_residual_test(test, n_samples: int, fs_hz: float = 250.0):
    """``test(context, fit)`` on an effect-free record of ``n_samples`` (the overnight folder's rate
    by default), timed apart from the full-rate residual it reads (computed first, as the workflow
    has it by then). Returns (the test's result, its CPU s, the residual's CPU s, the samples)."""
    prof = procedure_profile(n_samples / fs_hz, fs_hz, ramps_c_per_min=(1.0, 2.0, 1.0), dwell_s=60.0,
                             static_s=600.0)
    ctx, after = base_refit(prof, 1, max_bins=2000)
    start = time.process_time()
    ctx.resid_full(after)
    resid_s = time.process_time() - start
    start = time.process_time()
    result = test(ctx, after)
    return result, time.process_time() - start, resid_s, len(ctx.log)
