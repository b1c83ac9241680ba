"""Simulated gyro output from a :class:`GyroModel`: the equation plus noise plus output stage.

The simulated instruments read it block by block as simulated time moves, so
:class:`GyroSimulator` is stateful: each ``generate`` continues where the
previous one ended (time, thermal lag, hysteresis branch, table angle, noise
filters, pulse accumulator). :func:`simulate` is the whole-record
convenience for tests and the workflow. The output keeps the parts apart
(noise-free indicated rate, noise, quantization error) because the analysis
needs to know what truth it is looking at.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gyrocal.models import recursion
from gyrocal.models.gyro_model import GyroModel
from gyrocal.models.indicated import ModelInputs, ModelState, indicated_rate
from gyrocal.models.noise import NoiseGenerator
from gyrocal.models.pulse_counting import PulseCounter


class AliasingWarning(UserWarning):
    """A periodic effect sits above the Nyquist frequency of the chosen sample rate."""


@dataclass(frozen=True)
class GyroSamples:
    """One block of simulated gyro samples.

    gyro = scale_factor · (rate_ideal_dps + noise_dph/3600 + quantization_dps)
    """

    t_s: np.ndarray
    table_rate_dps: np.ndarray
    chamber_temp_c: np.ndarray
    sensor_temp_c: np.ndarray
    table_angle_deg: np.ndarray
    rate_ideal_dps: np.ndarray    # noise-free indicated rate ω_ind, deg/s
    noise_dph: np.ndarray         # w(t), deg/h
    quantization_dps: np.ndarray  # output-stage (pulse counting) error, deg/s; zeros without it
    gyro: np.ndarray              # output units

    def __len__(self) -> int:
        return len(self.t_s)

    def log_columns(self) -> dict[str, np.ndarray]:
        """The columns of a measured log (``gyro-model.md``), for writing CSV/Parquet."""
        return {
            "t_s": self.t_s,
            "table_rate_dps": self.table_rate_dps,
            "chamber_temp_c": self.chamber_temp_c,
            "gyro": self.gyro,
            "sensor_temp_c": self.sensor_temp_c,
            "table_angle_deg": self.table_angle_deg,
        }


def _markov(model: GyroModel) -> tuple[float, float] | None:
    effect = model.effect("markov_bias")
    return None if effect is None else (effect["sigma_dph"], effect["tau_s"])


def _check_sample_rate(model: GyroModel, fs_hz: float) -> None:
    if not fs_hz > 0:
        raise ValueError(f"sample rate must be > 0 Hz, got {fs_hz!r}")
    effect = model.effect("periodic_interference")
    if effect is not None and fs_hz < 2.0 * effect["freq_hz"]:
        warnings.warn(
            f"model {model.name!r}: periodic_interference at {effect['freq_hz']:g} Hz is above the"
            f" Nyquist frequency {fs_hz / 2:g} Hz of fs = {fs_hz:g} Hz; it will alias"
            f" (use fs > {2 * effect['freq_hz']:g} Hz)",
            AliasingWarning,
            stacklevel=3,
        )


class GyroSimulator:
    """A gyro that emits the model's output for given table rate and chamber temperature.

    ``seed`` makes the noise reproducible (None: fresh entropy); the same seed
    gives the same record however it is cut into blocks.
    """

    #: what a resumed dry run restores (models/sim_state.py)
    SIM_STATE = ("_noise", "_counter", "_index", "_state")

    def __init__(self, model: GyroModel, fs_hz: float, seed: int | None = None, t0_s: float = 0.0) -> None:
        _check_sample_rate(model, fs_hz)
        recursion.warm_up()     # the noise and thermal-lag loops, before any timed exchange
        self.model = model
        self.fs_hz = float(fs_hz)
        self.t0_s = float(t0_s)
        self._noise = NoiseGenerator(model.noise, self.fs_hz, seed, _markov(model))
        quantization = model.effect("quantization")
        self._counter = None if quantization is None else PulseCounter(quantization["pulse_arcsec"])
        self._index = 0
        self._state: ModelState | None = None

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """Noise drawn from ``seed`` from the next sample on (the noise states carry on)."""
        self._noise.reseed(seed)

    @property
    def samples_emitted(self) -> int:
        return self._index

    @property
    def t_next_s(self) -> float:
        """Time stamp of the next sample ``generate`` will emit."""
        return self.t0_s + self._index / self.fs_hz

    def generate(
        self,
        table_rate_dps,
        chamber_temp_c,
        table_angle_deg=None,
        *,
        sensor_temp_c=None,
        field_t=None,
        n: int | None = None,
    ) -> GyroSamples:
        """The next block of samples, one per input sample.

        Inputs are arrays of one length, or scalars held over ``n`` samples
        (``n`` is needed only when every input is a scalar). Measured
        ``table_angle_deg`` / ``sensor_temp_c`` replace ∫ω_t dt / the thermal lag;
        ``field_t`` is the field along the sensitive axis (magnetic_sensitivity).
        """
        if n is None:
            lengths = {np.size(x) for x in (table_rate_dps, chamber_temp_c, table_angle_deg, sensor_temp_c)
                       if x is not None and np.ndim(x) > 0}
            if len(lengths) > 1:
                raise ValueError(f"input arrays differ in length: {sorted(lengths)}")
            n = lengths.pop() if lengths else 1
        t_s = self.t0_s + (self._index + np.arange(n)) / self.fs_hz
        if n == 0:
            empty = np.zeros(0)
            return GyroSamples(t_s, *([empty] * 8))
        inputs = ModelInputs.of(t_s, table_rate_dps, chamber_temp_c, table_angle_deg, sensor_temp_c,
                                field_t)
        result = _emit(self.model, inputs, self._state, 1.0 / self.fs_hz, self._noise, self._counter)
        self._state = result[1]
        self._index += n
        return result[0]

    def skip_to(
        self,
        t_s: float,
        inputs_at: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray | None]],
        step_s: float = 1.0,
    ) -> None:
        """Jump to the sample at ``t_s`` without emitting the samples in between.

        A simulated gyro whose frames nobody reads (the orchestrator is waiting
        for a soak on simulated time) must not spend hours generating them,
        but its physics must not forget the span either: the thermal-lag
        sensor temperature, the hysteresis branch and the table angle are
        evolved through it on a ``step_s`` grid (exact for the thermal lag
        when the chamber temperature is piecewise linear on that grid).
        The noise processes simply continue from their last state, as if the
        span had not been there — a negligible error for the unread span.
        ``inputs_at(t)`` gives (table rate, chamber temperature, table angle or None).
        """
        k_target = int(round((t_s - self.t0_s) * self.fs_hz))
        if k_target <= self._index:
            return
        t_first = self.t_next_s
        t_last = self.t0_s + (k_target - 1) / self.fs_hz
        count = max(2, int(np.ceil((t_last - t_first) / step_s)) + 1)
        grid = np.linspace(t_first, t_last, count) if t_last > t_first else np.array([t_last])
        grid = self._fine_tail(grid)
        rate, chamber, angle = inputs_at(grid)
        ideal = indicated_rate(self.model, ModelInputs.of(grid, rate, chamber, angle), self._state)
        self._state = ideal.state
        self._index = k_target


    def _fine_tail(self, grid: np.ndarray) -> np.ndarray:
        """With a rate bandwidth, the skip's last ten time constants on the frame grid.

        The low-pass state at the end of a skip is what the first read frames start
        from. On the coarse grid a table turning a sinusoid (a frequency-response
        step's settle) is undersampled and that state is wrong; its decay would sit in
        the logged data as a transient (0.2-0.4 % of gain at 1-3 Hz for a 2 Hz
        bandwidth, measured). The filter forgets everything older than a few τ, so
        only the tail needs the frames' own spacing.
        """
        effect = self.model.effect("rate_bandwidth")
        if effect is None or grid.size < 2:
            return grid
        tail_s = 10.0 / (2.0 * np.pi * float(effect["bandwidth_hz"]))
        t_last = float(grid[-1])
        start = max(float(grid[0]), t_last - tail_s)
        fine = t_last - np.arange(int((t_last - start) * self.fs_hz) + 1)[::-1] / self.fs_hz
        return np.concatenate((grid[grid < fine[0]], fine))


def _emit(
    model: GyroModel,
    inputs: ModelInputs,
    state: ModelState | None,
    dt_s,
    noise: NoiseGenerator,
    counter: PulseCounter | None,
) -> tuple[GyroSamples, ModelState]:
    """Equation + noise + output stage for one block; shared by the simulator and simulate()."""
    n = len(inputs)
    ideal = indicated_rate(model, inputs, state, dt_s if np.ndim(dt_s) == 0 else None)
    noise_dph = noise.generate(n)
    rate_dps = ideal.rate_dps + noise_dph / 3600.0
    if counter is not None:
        counted_dps = counter.quantize(rate_dps, dt_s)
        quantization_dps = counted_dps - rate_dps
        rate_dps = counted_dps
    else:
        quantization_dps = np.zeros(n)
    samples = GyroSamples(
        t_s=inputs.t_s,
        table_rate_dps=inputs.table_rate_dps,
        chamber_temp_c=inputs.chamber_temp_c,
        sensor_temp_c=ideal.sensor_temp_c,
        table_angle_deg=ideal.table_angle_deg,
        rate_ideal_dps=ideal.rate_dps,
        noise_dph=noise_dph,
        quantization_dps=quantization_dps,
        gyro=model.scale_factor * rate_dps,
    )
    return samples, ideal.state


def simulate(
    model: GyroModel,
    t_s,
    table_rate_dps,
    chamber_temp_c,
    seed: int | None = None,
    table_angle_deg=None,
    sensor_temp_c=None,
    field_t=None,
) -> GyroSamples:
    """Simulate a whole record at the given time stamps (strictly increasing).

    The noise is generated at fs = 1/median(Δt); the equation and the pulse
    counter use the actual intervals, so slightly irregular logs are fine.
    """
    inputs = ModelInputs.of(t_s, table_rate_dps, chamber_temp_c, table_angle_deg, sensor_temp_c,
                            field_t)
    n = len(inputs)
    if n < 2:
        raise ValueError("simulate needs at least 2 time stamps to know the sample rate")
    dt = np.empty(n)
    dt[1:] = np.diff(inputs.t_s)
    dt[0] = dt[1]
    fs_hz = 1.0 / float(np.median(dt))
    _check_sample_rate(model, fs_hz)
    noise = NoiseGenerator(model.noise, fs_hz, seed, _markov(model))
    quantization = model.effect("quantization")
    counter = None if quantization is None else PulseCounter(quantization["pulse_arcsec"])
    samples, _ = _emit(model, inputs, None, dt, noise, counter)
    return samples
