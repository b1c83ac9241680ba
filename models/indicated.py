"""The deterministic part of the measurement equation, as a pure function of inputs.

ω_ind = (1 + 1e-6·s(T_s))·ω_t + NL(ω_t) + [b(T_s) + Σ bias effects] / 3600

The simulator adds noise and the output stage to this; the analysis and the
discrepancy workflow call it directly on measured inputs, and
:func:`effect_contribution_dph` isolates one catalogue effect's signature
(the model with the effect minus the model without it), so the workflow can
score each effect against a residual with exactly the physics the simulator
used. History-dependent inputs (thermal lag, hysteresis branch, integrated
table angle, temperature rate) are carried in a :class:`ModelState`, so
evaluating a record block by block equals evaluating it at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrocal.models.effects import EFFECTS
from gyrocal.models.gyro_model import GyroModel
from gyrocal.models.temperature import (
    HYSTERESIS_BAND_C,
    hysteresis_sign,
    temperature_rate_c_per_min,
    thermal_lag_c,
)


@dataclass(frozen=True)
class ModelInputs:
    """The signals the equation reads, one value per sample (spec units).

    ``table_angle_deg`` and ``sensor_temp_c`` are optional measured columns;
    when given they are used as they are instead of ∫ω_t dt and the
    thermal-lag model. ``field_t`` (magnetic field along the sensitive axis,
    T) is optional too: without it the field is taken as zero, so
    ``magnetic_sensitivity`` adds nothing.
    """

    t_s: np.ndarray
    table_rate_dps: np.ndarray
    chamber_temp_c: np.ndarray
    table_angle_deg: np.ndarray | None = None
    sensor_temp_c: np.ndarray | None = None
    field_t: np.ndarray | None = None

    @classmethod
    def of(
        cls,
        t_s,
        table_rate_dps,
        chamber_temp_c,
        table_angle_deg=None,
        sensor_temp_c=None,
        field_t=None,
    ) -> ModelInputs:
        """Arrays from array-likes; scalars are broadcast to the length of ``t_s``."""
        t = np.asarray(t_s, dtype=float).reshape(-1)
        n = len(t)

        def column(name: str, value) -> np.ndarray | None:
            if value is None:
                return None
            arr = np.asarray(value, dtype=float)
            if arr.ndim == 0:
                arr = np.full(n, float(arr))
            if arr.shape != (n,):
                raise ValueError(f"{name}: expected {n} samples (as t_s), got shape {arr.shape}")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise ValueError(f"{name}: non-finite value {float(arr[bad[0]])!r} at sample {int(bad[0])}")
            return arr

        column("t_s", t)
        if n > 1 and not np.all(np.diff(t) > 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise ValueError(f"t_s: not strictly increasing at sample {k} ({t[k - 1]!r} -> {t[k]!r})")
        return cls(
            t,
            column("table_rate_dps", table_rate_dps),
            column("chamber_temp_c", chamber_temp_c),
            column("table_angle_deg", table_angle_deg),
            column("sensor_temp_c", sensor_temp_c),
            column("field_t", field_t),
        )

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True)
class ModelState:
    """What the equation remembers between blocks: the last sample's history."""

    t_s: float
    chamber_temp_c: float
    sensor_temp_c: float
    table_rate_dps: float
    table_angle_deg: float
    hysteresis_sign: int
    hysteresis_extreme_c: float
    #: the rate the rate terms saw last (rate_bandwidth's low-pass output); None without it
    sensed_rate_dps: float | None = None


@dataclass(frozen=True)
class Indicated:
    """The noise-free indicated rate and the intermediate signals it was built from."""

    rate_dps: np.ndarray                     # ω_ind without w(t), deg/s
    sensor_temp_c: np.ndarray                # T_s used by every temperature term
    sensor_temp_rate_c_per_min: np.ndarray   # dT_s/dt
    table_angle_deg: np.ndarray              # θ used by table_angle_harmonic
    hysteresis_sign: np.ndarray              # h(t), +1/-1
    effective_rate_dps: np.ndarray           # ω_t after the dead zone
    scale_factor_error_ppm: np.ndarray       # s(T_s) incl. sf_temp_quadratic
    bias_dph: np.ndarray                     # b(T_s) + Σ bias effects
    state: ModelState


def _sample_intervals(t: np.ndarray, state: ModelState | None, dt_s: float | None):
    """dt[k] = t[k] − t[k−1] (the first from the state, else the next interval)."""
    if dt_s is not None:
        return float(dt_s)
    n = len(t)
    dt = np.empty(n)
    dt[1:] = np.diff(t)
    if state is not None:
        dt[0] = t[0] - state.t_s
    else:
        # no history: the first sample's interval is never used for a difference
        # (T_s(0) = T_c(0), dT_s/dt = 0, θ(0) = 0), any finite value will do
        dt[0] = dt[1] if n > 1 else 1.0
    return dt


def _integrated_angle_deg(
    rate_dps: np.ndarray, dt, state: ModelState | None
) -> np.ndarray:
    """θ = ∫ω_t dt by the trapezoid rule, from θ(0) = 0 or the state's angle."""
    n = len(rate_dps)
    step = np.empty(n)
    dt_arr = np.broadcast_to(np.asarray(dt, dtype=float), (n,))
    step[1:] = 0.5 * (rate_dps[1:] + rate_dps[:-1]) * dt_arr[1:]
    if state is None:
        step[0] = 0.0
        start = 0.0
    else:
        step[0] = 0.5 * (rate_dps[0] + state.table_rate_dps) * dt_arr[0]
        start = state.table_angle_deg
    return start + np.cumsum(step)


@dataclass(frozen=True)
class InputHistory:
    """What the equation derives from the inputs alone, whatever the model's parameters.

    A fit evaluates the equation on the same inputs dozens of times (once per
    regressor); the intervals, the integrated table angle, the hysteresis
    branch and the chamber's rate do not change between those calls, so
    :class:`gyrocal.analysis.discrepancy.signatures.DesignBuilder` computes them
    once (on a 10 M-sample overnight log: about half of each evaluation).
    """

    dt: np.ndarray
    angle_deg: np.ndarray
    branch: np.ndarray
    branch_end: int
    extreme_end_c: float
    chamber_rate_c_per_min: np.ndarray
    sensor_rate_c_per_min: np.ndarray | None   # of a measured sensor temperature, when logged


def input_history(inputs: ModelInputs, dt_s: float | None = None) -> InputHistory:
    """The model-independent part of :func:`indicated_rate` for a record evaluated from its start."""
    dt = _sample_intervals(inputs.t_s, None, dt_s)
    angle = (inputs.table_angle_deg if inputs.table_angle_deg is not None
             else _integrated_angle_deg(inputs.table_rate_dps, dt, None))
    branch, branch_end, extreme_end = hysteresis_sign(inputs.chamber_temp_c, 1, None,
                                                      HYSTERESIS_BAND_C)
    chamber_rate = temperature_rate_c_per_min(inputs.chamber_temp_c, dt, None)
    sensor_rate = (None if inputs.sensor_temp_c is None
                   else temperature_rate_c_per_min(inputs.sensor_temp_c, dt, None))
    return InputHistory(dt, np.asarray(angle), branch, int(branch_end), float(extreme_end),
                        chamber_rate, sensor_rate)


def indicated_rate(
    model: GyroModel,
    inputs: ModelInputs,
    state: ModelState | None = None,
    dt_s: float | None = None,
    history: InputHistory | None = None,
) -> Indicated:
    """Evaluate the deterministic equation on ``inputs``, continuing from ``state``.

    ``dt_s`` declares uniform sampling (the simulator passes 1/fs); without it
    the intervals are read from ``inputs.t_s``. Stochastic effects
    (``markov_bias``) and the output stage (``quantization``) are not part of
    this; see :mod:`gyrocal.models.noise` and :mod:`gyrocal.models.pulse_counting`.
    """
    n = len(inputs)
    if n == 0:
        raise ValueError("no samples to evaluate")
    t = inputs.t_s
    if history is not None and state is not None:
        raise ValueError("a precomputed input history is for a record evaluated from its start")
    dt = history.dt if history is not None else _sample_intervals(t, state, dt_s)
    omega = inputs.table_rate_dps
    chamber = inputs.chamber_temp_c
    fx = {e.name: e.params for e in model.effects}
    sensor, sensor_rate = _sensor_temperature(inputs, fx, dt, state, history)
    delta_t = sensor - model.reference_temp_c
    angle, branch, branch_end, extreme_end = _angle_and_branch(inputs, dt, state, history)
    sensed, omega_eff = _sensed_rate(omega, fx, dt, state)
    rate, sf_ppm = _rate_terms(model, fx, omega_eff, delta_t, n)
    bias = _bias_dph(model, fx, inputs, delta_t, sensor_rate, branch, angle)
    end = ModelState(
        t_s=float(t[-1]),
        chamber_temp_c=float(chamber[-1]),
        sensor_temp_c=float(sensor[-1]),
        table_rate_dps=float(omega[-1]),
        table_angle_deg=float(angle[-1]),
        hysteresis_sign=int(branch_end),
        hysteresis_extreme_c=float(extreme_end),
        sensed_rate_dps=float(sensed[-1]) if "rate_bandwidth" in fx else None,
    )
    return Indicated(
        rate_dps=rate + bias / 3600.0,
        sensor_temp_c=np.asarray(sensor),
        sensor_temp_rate_c_per_min=sensor_rate,
        table_angle_deg=np.asarray(angle),
        hysteresis_sign=branch,
        effective_rate_dps=np.asarray(omega_eff),
        scale_factor_error_ppm=sf_ppm,
        bias_dph=bias,
        state=end,
    )


_Effects = dict[str, dict[str, float]]


def _sensor_temperature(inputs: ModelInputs, fx: _Effects, dt: np.ndarray,
                        state: ModelState | None, history: InputHistory | None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's temperature (measured, lagging the chamber, or the chamber's) and its rate."""
    chamber = inputs.chamber_temp_c
    if inputs.sensor_temp_c is not None:
        sensor = inputs.sensor_temp_c
    elif "thermal_lag" in fx:
        sensor = thermal_lag_c(
            chamber,
            dt,
            fx["thermal_lag"]["tau_s"],
            None if state is None else state.sensor_temp_c,
            None if state is None else state.chamber_temp_c,
        )
    else:
        sensor = chamber
    if history is not None and sensor is chamber:
        sensor_rate = history.chamber_rate_c_per_min
    elif history is not None and history.sensor_rate_c_per_min is not None \
            and sensor is inputs.sensor_temp_c:
        sensor_rate = history.sensor_rate_c_per_min
    else:
        sensor_rate = temperature_rate_c_per_min(
            sensor, dt, None if state is None else state.sensor_temp_c
        )
    return sensor, sensor_rate


def _angle_and_branch(inputs: ModelInputs, dt: np.ndarray, state: ModelState | None,
                   history: InputHistory | None) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Table angle and hysteresis branch (with its end state), precomputed or from the inputs."""
    if history is not None:
        return history.angle_deg, history.branch, history.branch_end, history.extreme_end_c
    if inputs.table_angle_deg is not None:
        angle = inputs.table_angle_deg
    else:
        angle = _integrated_angle_deg(inputs.table_rate_dps, dt, state)
    branch, branch_end, extreme_end = hysteresis_sign(
        inputs.chamber_temp_c,
        1 if state is None else state.hysteresis_sign,
        None if state is None else state.hysteresis_extreme_c,
        HYSTERESIS_BAND_C,
    )
    return angle, branch, branch_end, extreme_end


def _sensed_rate(omega: np.ndarray, fx: _Effects, dt: np.ndarray,
                 state: ModelState | None) -> tuple[np.ndarray, np.ndarray]:
    """The sensing bandwidth first (a first-order low-pass of ω_t, the same first-order-hold
    solution as the thermal lag), then the dead zone; both replace ω_t in every rate term.
    Returns the band-limited rate and the effective rate after the dead zone."""
    sensed = omega
    if "rate_bandwidth" in fx:
        sensed = thermal_lag_c(omega, dt, 1.0 / (2.0 * np.pi * fx["rate_bandwidth"]["bandwidth_hz"]),
                               None if state is None else state.sensed_rate_dps,
                               None if state is None else state.table_rate_dps)
    omega_eff = sensed
    if "dead_zone" in fx:
        omega_eff = np.where(np.abs(sensed) < fx["dead_zone"]["threshold_dps"], 0.0, sensed)
    return sensed, omega_eff


# A term whose coefficient is 0 is skipped, not multiplied out (adding 0·x is exact
# for the finite inputs ModelInputs admits): a fit evaluates "unit" models with a
# single coefficient set, on 10 M samples each skipped term saves an array pass.
def _coefficient(fx: _Effects, effect: str, key: str) -> float:
    return float(fx[effect][key]) if effect in fx else 0.0


def _rate_terms(model: GyroModel, fx: _Effects, omega_eff: np.ndarray, delta_t: np.ndarray,
                n: int) -> tuple[np.ndarray, np.ndarray]:
    """The scale-factor bracket applied to the effective rate, deg/s, and the SF error, ppm."""
    sf_ppm = model.sf_error_ppm
    if model.sf_tempco_ppm_per_c != 0.0:
        sf_ppm = sf_ppm + model.sf_tempco_ppm_per_c * delta_t
    if (k := _coefficient(fx, "sf_temp_quadratic", "ppm_per_c2")) != 0.0:
        sf_ppm = sf_ppm + k * delta_t**2
    rate = omega_eff if np.ndim(sf_ppm) == 0 and sf_ppm == 0.0 else (1.0 + 1e-6 * sf_ppm) * omega_eff
    sf_ppm = np.broadcast_to(sf_ppm, (n,))
    if (k := _coefficient(fx, "sf_nonlinearity_quadratic", "k2_per_dps")) != 0.0:
        rate = rate + k * omega_eff**2
    if (k := _coefficient(fx, "sf_nonlinearity_cubic", "k3_per_dps2")) != 0.0:
        rate = rate + k * omega_eff**3
    if (k := _coefficient(fx, "sf_asymmetry", "ppm")) != 0.0:
        rate = rate + 0.5e-6 * k * np.abs(omega_eff)
    if "rate_saturation" in fx:
        # the input-rate limit: the output follows the rate up to it, then stays there
        rate = np.clip(rate, -fx["rate_saturation"]["negative_dps"],
                       fx["rate_saturation"]["positive_dps"])
    return rate, sf_ppm


def _bias_dph(model: GyroModel, fx: _Effects, inputs: ModelInputs, delta_t: np.ndarray,
              sensor_rate: np.ndarray, branch: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The bias bracket, deg/h, one value per sample."""
    t = inputs.t_s
    bias = model.bias_dph + model.earth_rate_dph
    if model.bias_tempco_dph_per_c != 0.0:
        bias = bias + model.bias_tempco_dph_per_c * delta_t
    if (k := _coefficient(fx, "temp_rate_bias", "dph_per_c_per_min")) != 0.0:
        bias = bias + k * sensor_rate
    if (k := _coefficient(fx, "temp_hysteresis", "dph")) != 0.0:
        bias = bias + k * branch
    if (k := _coefficient(fx, "bias_temp_quadratic", "dph_per_c2")) != 0.0:
        bias = bias + k * delta_t**2
    if (k := _coefficient(fx, "warmup_transient", "amplitude_dph")) != 0.0:
        bias = bias + k * np.exp(-t / fx["warmup_transient"]["tau_s"])
    if (k := _coefficient(fx, "bias_ramp", "dph_per_h")) != 0.0:
        bias = bias + k * t / 3600.0
    if (k := _coefficient(fx, "table_angle_harmonic", "amplitude_dph")) != 0.0:
        bias = bias + k * np.cos(np.deg2rad(angle - fx["table_angle_harmonic"]["phase_deg"]))
    if (k := _coefficient(fx, "periodic_interference", "amplitude_dph")) != 0.0:
        bias = bias + k * np.sin(2.0 * np.pi * fx["periodic_interference"]["freq_hz"] * t)
    if (k := _coefficient(fx, "magnetic_sensitivity", "dph_per_t")) != 0.0 \
            and inputs.field_t is not None:
        bias = bias + k * inputs.field_t
    return np.broadcast_to(bias, (len(inputs),))


def effect_contribution_dph(
    model: GyroModel, name: str, inputs: ModelInputs, state: ModelState | None = None
) -> np.ndarray:
    """What catalogue effect ``name`` (as parametrised in ``model``) adds to ω_ind, in deg/h.

    Computed as ω_ind(model) − ω_ind(model without the effect), input-referred
    and ×3600, so effects that act through other terms (thermal_lag through
    every temperature term, dead_zone through every rate term) get their true
    signature, interactions included. For an effect linear in one amplitude,
    the signature at amplitude 1 is the least-squares regressor of that
    amplitude. ``markov_bias`` (stochastic) and ``quantization`` (output stage)
    have no deterministic signature here and are refused.
    """
    definition = EFFECTS.get(name)
    if definition is None:
        raise KeyError(f"unknown effect {name!r}; known effects: {', '.join(EFFECTS)}")
    if definition.target in ("noise", "output"):
        raise ValueError(
            f"effect {name!r} acts on the {'noise' if definition.target == 'noise' else 'output stage'}"
            " and has no deterministic rate signature"
        )
    if not model.has_effect(name):
        raise ValueError(f"model {model.name!r} has no effect {name!r}; add it with with_effect()")
    with_it = indicated_rate(model, inputs, state).rate_dps
    without = indicated_rate(model.without_effect(name), inputs, state).rate_dps
    return (with_it - without) * 3600.0
