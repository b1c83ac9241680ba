"""One log under analysis: its inputs, bins, design builder and current whitening.

Built once per analysis and read by every pass (workflow.py), candidate
(candidates.py) and rule (markov_rules.py). The whitening is the one piece that
changes: the noise pass sets it, and an accepted Markov bias joins it
(``with_noise``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import optimize

from gyrocal.analysis.discrepancy.noise_model import NoiseModel
from gyrocal.analysis.discrepancy.periodic import PeriodicScan, periodic_scan
from gyrocal.analysis.discrepancy.probes import ProbeInputs
from gyrocal.analysis.discrepancy.scoring import Fit, Whitener, gls_fit
from gyrocal.analysis.discrepancy.segments import (
    derive_segments,
    make_bins,
    temperature_trend_c_per_min,
)
from gyrocal.analysis.discrepancy.signatures import (
    DesignBuilder,
    SearchSpace,
    passed_rates,
    rate_levels,
)
from gyrocal.analysis.discrepancy.stochastic import (
    MARKOV,
    StochasticCandidate,
    WhittleTest,
    fine_bins,
)
from gyrocal.analysis.measured_log import LogFormatError, MeasuredLog
from gyrocal.models.gyro_model import EffectSpec, GyroModel, ModelError
from gyrocal.models.indicated import ModelInputs
from gyrocal.models.rate_units import output_to_dph


class Context:
    """State shared by the passes: inputs, bins, design builder, whitening."""

    def __init__(self, model: GyroModel, log: MeasuredLog, seed: int, n_null: int,
                 max_bins: int) -> None:
        self.log = log
        try:
            self.inputs = ModelInputs.of(log.t_s, log.table_rate_dps, log.chamber_temp_c,
                                         log.table_angle_deg, log.sensor_temp_c,
                                         log.field_t)
        except ValueError as exc:
            raise LogFormatError(f"{log.source}: {exc}") from None
        self.fs_hz = log.sample_rate_hz
        try:
            self.bins = make_bins(log.t_s, self.fs_hz, max_bins=max_bins)
        except ValueError as exc:
            raise LogFormatError(f"{log.source}: {exc}") from None
        self.segments = derive_segments(log.t_s, log.table_rate_dps, log.chamber_temp_c, log.segment)
        self.builder = DesignBuilder(self.inputs, self.bins)
        self.y_full = output_to_dph(log.gyro, model.scale_factor)
        self.y_bins = self.bins.mean(self.y_full)
        self.rate_bins_dps = self.bins.mean(log.table_rate_dps)
        #: the rate-temperature probes' ΔT is about it, as the model's tempco laws are
        self.reference_temp_c = model.reference_temp_c
        self._probe_full: ProbeInputs | None = None
        self.probe_bins = self.probe_inputs(binned=True)
        self.space = SearchSpace(float(log.t_s[-1] - log.t_s[0]), self.bins.width_s,
                                 rate_levels(log.table_rate_dps, self.fs_hz),
                                 passed_rates(log.table_rate_dps), 1.0 / self.fs_hz)
        self.rng = np.random.default_rng(seed)
        self.n_null = n_null
        self.whitener: Whitener | None = None
        self.noise: NoiseModel | None = None
        #: the last full-rate residual, by its model's repr (read-only: it is shared)
        self._resid: tuple[str, np.ndarray] | None = None
        #: periodic scans by (model, noise model) repr
        self._scans: dict[tuple[str, str], PeriodicScan | None] = {}

    def probe_inputs(self, binned: bool = False) -> ProbeInputs:
        """The probes' inputs per sample (binned shapes with ``binned``)."""
        if self._probe_full is None:
            log = self.log
            # the chamber trend on the bins, interpolated back: the probes' dT/dt shapes need no
            # more (a per-sample trend of a 10 M-sample overnight log cost a second for nothing)
            trend_bins = temperature_trend_c_per_min(self.bins.centre_s, self.bins.mean(log.chamber_temp_c))
            trend = np.interp(log.t_s - log.t_s[0], self.bins.centre_s, trend_bins)
            self._probe_full = ProbeInputs(log.t_s - log.t_s[0], log.table_rate_dps, log.chamber_temp_c,
                                           trend, reference_temp_c=self.reference_temp_c)
        return replace(self._probe_full, bins=self.bins, _cache={}) if binned else self._probe_full

    def use_noise(self, noise: NoiseModel, model_name: str = "the gyro model") -> None:
        self.noise = noise
        cov = noise.bin_covariance(self.bins.centre_s, self.bins.width_s,
                                   self.bins.samples_per_bin, self.fs_hz)
        if not np.all(np.isfinite(cov)) or not np.all(np.diag(cov) > 0):
            # A valid model may leave out `noise:`; with too little quiet data to measure
            # it, no significance can be judged: say so rather than fail in the algebra.
            raise ModelError(
                f"{model_name}: the model has no noise terms (noise: block missing or "
                "all zero) and the measured log has too little quiet data to estimate them; "
                "add the gyro's noise: block (gyro-model.md) to the model file")
        self.whitener = Whitener(cov)

    def fit(self, model: GyroModel) -> Fit:
        return gls_fit(self.builder, self.whitener, self.y_bins, model)

    def resid_full(self, fit: Fit) -> np.ndarray:
        """The full-rate residual of ``fit``'s model, deg/h (read-only, shared by the callers).

        The last one is kept: the gap pass's tests (periodic scans, noise level, drifting
        line, spikes, the Markov test) read the same final model's residual, and on a
        10 M-sample record each fresh one cost an equation evaluation and 80 MB of new pages
        (seven of the eight per overnight analysis were the same residual).
        """
        key = repr(fit.model)
        if self._resid is None or self._resid[0] != key:
            self._resid = None   # the old one goes before the new one is made
            resid = self.builder.rate_dph(fit.model)
            np.subtract(self.y_full, resid, out=resid)
            resid.flags.writeable = False
            self._resid = (key, resid)
        return self._resid[1]

    def scan(self, fit: Fit) -> PeriodicScan | None:
        """The full-rate spectrum's strongest line, once per (model, noise model).

        A round's proposal and the gap pass's before/after scans are often of the same
        refit (nothing named, or nothing changed since): each scan of an overnight
        record is a 10 M-point FFT and the line's refinement, about a second.
        """
        key = (repr(fit.model), repr(self.noise))
        if key not in self._scans:
            self._scans[key] = periodic_scan(self.resid_full(fit), self.fs_hz, self.noise,
                                             0.5 / self.bins.width_s, self.log.t_s)
        return self._scans[key]


def refine_found(ctx: Context, model: GyroModel, names: list[str]) -> GyroModel:
    """Joint refit of the found effects' τ (bounded scalar search in log τ, one pass each)."""
    for name in names:
        spec = model.effect(name)
        if spec is None or "tau_s" not in spec.params or name == MARKOV:
            continue
        tau0 = spec["tau_s"]

        def chi2(log_tau: float, name=name, spec=spec, model=model) -> float:
            trial = model.with_effect(EffectSpec(name, {**spec.params, "tau_s": math.exp(log_tau)}))
            return ctx.fit(trial).chi2

        found = optimize.minimize_scalar(chi2, bounds=(math.log(tau0 / 2.0), math.log(tau0 * 2.0)),
                                         method="bounded", options={"maxiter": 10, "xatol": 1e-3})
        if found.fun < chi2(math.log(tau0)):
            model = model.with_effect(EffectSpec(name, {**spec.params, "tau_s": math.exp(found.x)}))
    return ctx.fit(model).model


def markov_test(ctx: Context, fit: Fit) -> StochasticCandidate:
    """The whole-record Markov alternative on one-second bins of the fit's full-rate residual."""
    return markov_test_of(ctx, ctx.resid_full(fit))


def markov_test_of(ctx: Context, resid_dph: np.ndarray) -> StochasticCandidate:
    bins = fine_bins(ctx.log.t_s, ctx.fs_hz)
    test = WhittleTest(ctx.noise, bins, ctx.fs_hz)
    return test.test(bins.mean(resid_dph), ctx.rng, ctx.n_null)
