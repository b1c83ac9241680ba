"""The effect catalogue of the gyro measurement model, as one table.

Validation of model files, the simulator and the discrepancy workflow (which
refits parameters and scores each effect against measured data) all read
:data:`EFFECTS`, so an effect's name, parameter keys, ranges and the split
between linear amplitudes and nonlinear shape parameters can never drift
apart between them. Names and keys are the contract of
``/work/shared/spec/gyro-model.md``; a name, once given, keeps its meaning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

#: Where an effect enters the equation (it decides the unit of its signature):
#: ``bias`` adds to the deg/h bracket, ``rate`` adds to NL(ω_t) in deg/s,
#: ``scale_factor`` adds to s(T) in ppm, ``temperature`` changes T_s for every
#: temperature term, ``table_rate`` changes ω_t for every rate term,
#: ``noise`` adds a stochastic process to w(t), ``output`` acts on the output
#: stage (pulse counting).
Target = Literal["bias", "rate", "scale_factor", "temperature", "table_rate", "noise", "output"]

#: ``linear``: the effect's contribution is proportional to this parameter
#: (an amplitude: least squares can fit it directly). ``nonlinear``: a time
#: constant, frequency, threshold, phase or pulse size that shapes the
#: signature and needs a search or an iterative fit.
ParamKind = Literal["linear", "nonlinear"]


@dataclass(frozen=True)
class ParamDef:
    """One parameter of a catalogue effect: its key, unit, kind and range."""

    key: str
    unit: str
    kind: ParamKind
    minimum: float = -math.inf
    minimum_exclusive: bool = False
    description: str = ""

    def check(self, value: float) -> str | None:
        """Return why ``value`` is out of range, or None when it is acceptable."""
        if not math.isfinite(value):
            return f"must be a finite number, got {value!r}"
        if self.minimum_exclusive and not value > self.minimum:
            return f"must be > {self.minimum:g}, got {value:g}"
        if not self.minimum_exclusive and value < self.minimum:
            return f"must be >= {self.minimum:g}, got {value:g}"
        return None

    @property
    def constraint(self) -> str:
        """The range in words, for messages and documentation."""
        if self.minimum == -math.inf:
            return "any finite number"
        return f"{'>' if self.minimum_exclusive else '>='} {self.minimum:g}"


@dataclass(frozen=True)
class EffectDef:
    """A catalogue entry: what the effect is called, reads and adds."""

    name: str
    params: tuple[ParamDef, ...]
    target: Target
    equation: str
    cause: str

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.params)

    @property
    def linear_keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.params if p.kind == "linear")

    @property
    def nonlinear_keys(self) -> tuple[str, ...]:
        return tuple(p.key for p in self.params if p.kind == "nonlinear")

    @property
    def stochastic(self) -> bool:
        """True when the effect has no deterministic signature (only a noise signature)."""
        return self.target == "noise"

    def param(self, key: str) -> ParamDef:
        for p in self.params:
            if p.key == key:
                return p
        raise KeyError(f"effect {self.name!r} has no parameter {key!r}; it has {list(self.keys)}")


def _positive(key: str, unit: str, kind: ParamKind, description: str) -> ParamDef:
    return ParamDef(key, unit, kind, 0.0, True, description)


def _any(key: str, unit: str, kind: ParamKind, description: str) -> ParamDef:
    return ParamDef(key, unit, kind, description=description)


_CATALOGUE: tuple[EffectDef, ...] = (
    EffectDef(
        "thermal_lag",
        (_positive("tau_s", "s", "nonlinear", "sensor thermal time constant"),),
        "temperature",
        "dT_s/dt = (T_c - T_s)/tau_s, T_s(0) = T_c(0); every temperature term uses T_s",
        "sensor lags the chamber air",
    ),
    EffectDef(
        "temp_rate_bias",
        (_any("dph_per_c_per_min", "deg/h per degC/min", "linear", "bias per sensor temperature rate"),),
        "bias",
        "bias += k * dT_s/dt, dT_s/dt in degC/min",
        "Shupe effect (FOG), thermal gradients",
    ),
    EffectDef(
        "temp_hysteresis",
        (_any("dph", "deg/h", "linear", "half the bias step between heating and cooling branches"),),
        "bias",
        "bias += dph * h(t); h = +1 after the chamber last rose, -1 after it last fell",
        "hysteresis between heating and cooling branches",
    ),
    EffectDef(
        "bias_temp_quadratic",
        (_any("dph_per_c2", "deg/h/degC^2", "linear", "curvature of the bias-temperature law"),),
        "bias",
        "bias += k * dT^2",
        "curved bias-temperature law",
    ),
    EffectDef(
        "sf_temp_quadratic",
        (_any("ppm_per_c2", "ppm/degC^2", "linear", "curvature of the scale-factor-temperature law"),),
        "scale_factor",
        "s += k * dT^2",
        "curved scale-factor-temperature law",
    ),
    EffectDef(
        "sf_nonlinearity_quadratic",
        (_any("k2_per_dps", "1/(deg/s)", "linear", "even-order rate nonlinearity"),),
        "rate",
        "rate += k2 * w_t^2",
        "even-order nonlinearity",
    ),
    EffectDef(
        "sf_nonlinearity_cubic",
        (_any("k3_per_dps2", "1/(deg/s)^2", "linear", "odd-order rate nonlinearity"),),
        "rate",
        "rate += k3 * w_t^3",
        "odd-order nonlinearity",
    ),
    EffectDef(
        "sf_asymmetry",
        (_any("ppm", "ppm", "linear", "scale-factor difference between + and - rates"),),
        "rate",
        "rate += 0.5e-6 * ppm * |w_t|",
        "asymmetric scale factor",
    ),
    EffectDef(
        "dead_zone",
        (_positive("threshold_dps", "deg/s", "nonlinear", "rates below this read as zero"),),
        "table_rate",
        "w_t is replaced by 0 in every rate term where |w_t| < threshold",
        "lock-in (RLG), dead band",
    ),
    EffectDef(
        "rate_bandwidth",
        (_positive("bandwidth_hz", "Hz", "nonlinear", "-3 dB frequency of the first-order "
                   "rate response"),),
        "table_rate",
        "w_t is replaced by its first-order low-pass, tau = 1/(2 pi bandwidth_hz), in every "
        "rate term: gain 1/sqrt(1 + (f/f_c)^2), phase -atan(f/f_c)",
        "closed-loop or filter bandwidth of the rate output (frequency response)",
    ),
    EffectDef(
        "rate_saturation",
        (
            _positive("positive_dps", "deg/s", "nonlinear", "largest positive rate the output "
                      "follows (the unit's input limit)"),
            _positive("negative_dps", "deg/s", "nonlinear", "largest negative rate magnitude "
                      "the output follows"),
        ),
        "rate",
        "rate (every rate term summed) is clipped to [-negative_dps, +positive_dps]",
        "input-rate limit: the loop or the output range saturates",
    ),
    EffectDef(
        "warmup_transient",
        (
            _any("amplitude_dph", "deg/h", "linear", "bias excess at power-on"),
            _positive("tau_s", "s", "nonlinear", "warm-up time constant"),
        ),
        "bias",
        "bias += A * exp(-t/tau_s)",
        "warm-up after power-on",
    ),
    EffectDef(
        "bias_ramp",
        (_any("dph_per_h", "deg/h/h", "linear", "slope of the bias drift"),),
        "bias",
        "bias += r * t/3600",
        "slow monotonic drift",
    ),
    EffectDef(
        "table_angle_harmonic",
        (
            _any("amplitude_dph", "deg/h", "linear", "once-per-revolution bias amplitude"),
            _any("phase_deg", "deg", "nonlinear", "table angle of the maximum"),
        ),
        "bias",
        "bias += A * cos(theta - phase)",
        "input-axis tilt sensing Earth's horizontal rate, table wobble, room magnetic field",
    ),
    EffectDef(
        "periodic_interference",
        (
            _positive("freq_hz", "Hz", "nonlinear", "interference line frequency"),
            _any("amplitude_dph", "deg/h", "linear", "interference amplitude"),
        ),
        "bias",
        "bias += A * sin(2 pi f t)",
        "turntable motor/drive interference (12.48 Hz line and harmonics reported)",
    ),
    EffectDef(
        "magnetic_sensitivity",
        (_any("dph_per_t", "deg/(h*T)", "linear", "bias per tesla of field along the sensitive "
              "axis (vendor notes: ~1e4 unshielded, 1-10 navigation grade)"),),
        "bias",
        "bias += k * B, B = field along the sensitive axis in T (the field_t input; 0 without it)",
        "Faraday effect in the FOG coil (magnetic bias sensitivity)",
    ),
    EffectDef(
        "markov_bias",
        (
            ParamDef("sigma_dph", "deg/h", "linear", 0.0, False, "steady-state standard deviation"),
            _positive("tau_s", "s", "nonlinear", "correlation time"),
        ),
        "noise",
        "w += first-order Gauss-Markov process (std sigma, correlation time tau)",
        "exponentially correlated noise (Allan hump at tau ~ 1.89 tau_s)",
    ),
    EffectDef(
        "quantization",
        (_positive("pulse_arcsec", "arcsec", "nonlinear", "angle per output pulse"),),
        "output",
        "output = sf * (floor(Theta_k/q) - floor(Theta_{k-1}/q)) * q * fs, Theta_k = sum(w_ind/fs)",
        "pulse counting (RLG); the error stays bounded in angle",
    ),
)

#: The catalogue, by effect name (the order is the spec's order).
EFFECTS: dict[str, EffectDef] = {e.name: e for e in _CATALOGUE}

