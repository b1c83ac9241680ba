"""Temperature-chamber air physics for the simulated chambers and the simulated gyro.

A calibration run spends most of its night waiting for the chamber, so the
simulation must be cheap to jump forward by hours and must still behave like a
real chamber: the air approaches the setpoint exponentially (first order,
time constant ``tau_s``) but never faster than the heater or the compressor
allows (ramp-rate limits). Between two setpoint changes this has a closed
form, so the model keeps a short list of *segments* (start time, start
temperature, target, rate limits) and evaluates any time inside them exactly;
nothing is integrated and nothing needs stepping. "Advancing to now" is just
evaluating the current segment at ``clock.now_s()``.

Closed form of one segment, with error ``e = target - air`` and the rate limit
``r`` of the direction of travel (heating or cooling): while
``|e| > r * tau_s`` the slope ``|e| / tau_s`` would exceed the limit, so the air
ramps linearly at ``r``; from ``|e| = r * tau_s`` on it decays as
``|e| = r * tau_s * exp(-t / tau_s)``. The slope is continuous at the switch.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from gyrocal.models.clock import Clock
from gyrocal.models.sim_state import SIM_HISTORY_S, decode, encode


@dataclass(frozen=True)
class _Segment:
    """Constant-target stretch of the air response, valid from ``t0_s`` on."""

    t0_s: float
    air0_c: float
    target_c: float
    heat_cps: float     # heating rate limit, °C/s
    cool_cps: float     # cooling rate limit, °C/s


@dataclass(frozen=True)
class AlarmState:
    """Whether the chamber is in alarm, and in words why (for the journal)."""

    active: bool
    detail: str = ""


def _segment_air_c(seg: _Segment, tau_s: float, t_s: np.ndarray) -> np.ndarray:
    """Exact air temperature of one segment at times ``t_s >= seg.t0_s``."""
    dt_s = np.maximum(np.asarray(t_s, dtype=float) - seg.t0_s, 0.0)
    err0_c = seg.target_c - seg.air0_c
    if err0_c == 0.0:
        return np.full_like(dt_s, seg.target_c)
    sign = 1.0 if err0_c > 0 else -1.0
    rate_cps = seg.heat_cps if err0_c > 0 else seg.cool_cps
    abs_err0_c = abs(err0_c)
    switch_err_c = rate_cps * tau_s
    if abs_err0_c > switch_err_c:
        ramp_s = (abs_err0_c - switch_err_c) / rate_cps
        abs_err_c = np.where(
            dt_s <= ramp_s,
            abs_err0_c - rate_cps * dt_s,
            switch_err_c * np.exp(-(dt_s - ramp_s) / tau_s),
        )
    else:
        abs_err_c = abs_err0_c * np.exp(-dt_s / tau_s)
    return seg.target_c - sign * abs_err_c


class ChamberPhysics:
    """Air temperature of one chamber, evaluated lazily at the shared clock's time.

    Thread-safe: the Modbus simulator thread, the simulated gyro and the test
    all ask it questions concurrently.

    ``stuck`` models the fault "never reaches setpoint": heater and compressor
    work at ``stuck_capacity`` of their power, so both the ramp limits and the
    reachable temperature shrink (the air settles at
    ``ambient + capacity * (setpoint - ambient)``) and the PV stalls short.

    Alarms: a *process* alarm when the air leaves ``[alarm_low_c, alarm_high_c]``
    (default: the setpoint limits), and, if ``alarm_band_c`` is set, a
    *deviation* alarm when the air is further than the band from the setpoint.
    Like a Watlow deviation alarm with "blocking", the deviation alarm only arms
    once the air has been inside the band since the last setpoint change, so an
    ordinary ramp does not raise it.
    """

    _SEGMENTS_KEPT = 100_000   # a night of 10 s software-ramp steps is ~10⁴ segments

    def __init__(
        self,
        clock: Clock,
        ambient_c: float = 22.0,
        tau_s: float = 300.0,
        max_heat_c_per_min: float = 5.0,
        max_cool_c_per_min: float = 3.5,
        min_setpoint_c: float = -70.0,
        max_setpoint_c: float = 180.0,
        noise_c: float = 0.05,
        seed: int | None = None,
        *,
        initial_c: float | None = None,
        alarm_low_c: float | None = None,
        alarm_high_c: float | None = None,
        alarm_band_c: float | None = None,
        stuck_capacity: float = 0.6,
    ) -> None:
        if not tau_s > 0:
            raise ValueError(f"tau_s must be > 0, got {tau_s!r}")
        if not (max_heat_c_per_min > 0 and max_cool_c_per_min > 0):
            raise ValueError("ramp-rate limits must be > 0 °C/min")
        if not min_setpoint_c < max_setpoint_c:
            raise ValueError(f"min_setpoint_c {min_setpoint_c} must be < max_setpoint_c {max_setpoint_c}")
        if noise_c < 0:
            raise ValueError(f"noise_c must be >= 0, got {noise_c!r}")
        if not 0 < stuck_capacity < 1:
            raise ValueError(f"stuck_capacity must be in (0, 1), got {stuck_capacity!r}")
        self.clock = clock
        self.ambient_c = float(ambient_c)
        self.tau_s = float(tau_s)
        self.max_heat_c_per_min = float(max_heat_c_per_min)
        self.max_cool_c_per_min = float(max_cool_c_per_min)
        self.min_setpoint_c = float(min_setpoint_c)
        self.max_setpoint_c = float(max_setpoint_c)
        self.noise_c = float(noise_c)
        self.alarm_low_c = float(min_setpoint_c if alarm_low_c is None else alarm_low_c)
        self.alarm_high_c = float(max_setpoint_c if alarm_high_c is None else alarm_high_c)
        self.alarm_band_c = None if alarm_band_c is None else float(alarm_band_c)
        self.stuck_capacity = float(stuck_capacity)
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._stuck = False
        self._setpoint_c = self.ambient_c
        start_c = self.ambient_c if initial_c is None else float(initial_c)
        self._segments: deque[_Segment] = deque(maxlen=self._SEGMENTS_KEPT)
        self._segments.append(self._make_segment(clock.now_s(), start_c))
        self._band_reached_before_segment = False

    # ------------------------------------------------------------------ setpoint
    @property
    def setpoint_c(self) -> float:
        with self._lock:
            return self._setpoint_c

    def set_setpoint(self, value_c: float) -> None:
        """Change the setpoint now; refuses values outside the chamber's range."""
        value_c = float(value_c)
        if not math.isfinite(value_c) or not (self.min_setpoint_c <= value_c <= self.max_setpoint_c):
            raise ValueError(
                f"setpoint {value_c} °C outside the chamber range "
                f"[{self.min_setpoint_c}, {self.max_setpoint_c}] °C"
            )
        with self._lock:
            self._setpoint_c = value_c
            self._band_reached_before_segment = False
            self._start_segment()

    # --------------------------------------------------------------------- stuck
    @property
    def stuck(self) -> bool:
        with self._lock:
            return self._stuck

    @stuck.setter
    def stuck(self, value: bool) -> None:
        with self._lock:
            if bool(value) == self._stuck:
                return
            self._band_reached_before_segment = (
                self._band_reached_before_segment or self._band_reached_in_segment(self.clock.now_s())
            )
            self._stuck = bool(value)
            self._start_segment()

    # --------------------------------------------------------------- evaluation
    def air_temperature_c(self, t_s: np.ndarray | float) -> np.ndarray:
        """True (noise-free) air temperature at the given times, vectorised.

        Times may lie anywhere inside the kept segments (the last
        ``_SEGMENTS_KEPT`` setpoint changes), typically a block of gyro frame
        times at or just after now. Times in the future are the prediction of
        the current segment (valid until someone changes the setpoint).
        """
        times_s = np.atleast_1d(np.asarray(t_s, dtype=float))
        earliest_s = float(times_s.min()) if times_s.size else np.inf
        with self._lock:
            # Walk back from the newest segment only as far as the earliest time asked
            # for: usually one or two segments, however long the kept history is.
            segments = []
            for seg in reversed(self._segments):
                segments.append(seg)
                if seg.t0_s <= earliest_s + 1e-9:
                    break
        segments.reverse()
        first_t_s = segments[0].t0_s
        if times_s.size and earliest_s < first_t_s - 1e-9:
            raise ValueError(
                f"chamber history starts at t={first_t_s:.3f} s; cannot evaluate t={earliest_s:.3f} s"
            )
        starts_s = np.array([seg.t0_s for seg in segments])
        which = np.clip(np.searchsorted(starts_s, times_s, side="right") - 1, 0, len(segments) - 1)
        out_c = np.empty_like(times_s)
        for index in np.unique(which):
            mask = which == index
            out_c[mask] = _segment_air_c(segments[index], self.tau_s, times_s[mask])
        return out_c

    def true_temperature_c(self, t_s: float | None = None) -> float:
        """Noise-free air temperature at ``t_s`` (default: now)."""
        when_s = self.clock.now_s() if t_s is None else float(t_s)
        return float(self.air_temperature_c(when_s)[0])

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """Measurement noise drawn from ``seed`` from now on (a dry run's attempt)."""
        self._rng = np.random.default_rng(seed)

    def sim_state(self) -> dict:
        """What a resumed dry run restores (``models/sim_state.py``): setpoint, stuck flag,
        noise stream and the air's recent history (the segments of the last
        :data:`SIM_HISTORY_S`: a simulated gyro asks for frames at most a block behind now)."""
        with self._lock:
            segments = list(self._segments)
            since_s = self.clock.now_s() - SIM_HISTORY_S
            first = max((i for i, seg in enumerate(segments) if seg.t0_s <= since_s), default=0)
            return {"rng": encode(self._rng), "stuck": self._stuck,
                    "setpoint_c": self._setpoint_c,
                    "band_reached_before_segment": self._band_reached_before_segment,
                    "segments": encode(segments[first:])}

    def restore_sim_state(self, state: dict) -> None:
        with self._lock:
            self._rng = decode(state["rng"], self._rng)
            self._stuck = bool(state["stuck"])
            self._setpoint_c = float(state["setpoint_c"])
            self._band_reached_before_segment = bool(state["band_reached_before_segment"])
            self._segments = deque(decode(state["segments"]), maxlen=self._SEGMENTS_KEPT)

    def temperature_c(self, t_s: float | None = None) -> float:
        """Measured process value: air temperature plus measurement noise."""
        true_c = self.true_temperature_c(t_s)
        if self.noise_c == 0:
            return true_c
        with self._lock:
            noise_c = float(self._rng.normal(0.0, self.noise_c))
        return true_c + noise_c

    def alarm_state(self, t_s: float | None = None) -> AlarmState:
        """Process alarm (outside the allowed range) or armed deviation alarm."""
        when_s = self.clock.now_s() if t_s is None else float(t_s)
        air_c = self.true_temperature_c(when_s)
        if air_c < self.alarm_low_c:
            return AlarmState(True, f"process low: {air_c:.2f} °C < {self.alarm_low_c:.2f} °C")
        if air_c > self.alarm_high_c:
            return AlarmState(True, f"process high: {air_c:.2f} °C > {self.alarm_high_c:.2f} °C")
        if self.alarm_band_c is not None:
            with self._lock:
                armed = self._band_reached_before_segment or self._band_reached_in_segment(when_s)
                setpoint_c = self._setpoint_c
            deviation_c = air_c - setpoint_c
            if armed and abs(deviation_c) > self.alarm_band_c:
                return AlarmState(
                    True,
                    f"deviation {deviation_c:+.2f} °C from setpoint {setpoint_c:.2f} °C "
                    f"exceeds ±{self.alarm_band_c:.2f} °C",
                )
        return AlarmState(False, "")

    # ------------------------------------------------------------------ private
    def _rates_cps(self) -> tuple[float, float]:
        scale = self.stuck_capacity if self._stuck else 1.0
        return self.max_heat_c_per_min / 60.0 * scale, self.max_cool_c_per_min / 60.0 * scale

    def _target_c(self) -> float:
        if not self._stuck:
            return self._setpoint_c
        return self.ambient_c + self.stuck_capacity * (self._setpoint_c - self.ambient_c)

    def _make_segment(self, t0_s: float, air0_c: float) -> _Segment:
        heat_cps, cool_cps = self._rates_cps()
        return _Segment(t0_s, air0_c, self._target_c(), heat_cps, cool_cps)

    def _start_segment(self) -> None:
        now_s = self.clock.now_s()
        air_c = float(_segment_air_c(self._segments[-1], self.tau_s, np.array([now_s]))[0])
        if self._segments[-1].t0_s >= now_s:
            self._segments.pop()   # several changes at the same instant: keep the last
        self._segments.append(self._make_segment(now_s, air_c))

    def _band_reached_in_segment(self, t_s: float) -> bool:
        """Has the air been within the band since the current segment began?

        The air is monotone inside a segment, so the closest approach to the
        setpoint is at an end, or zero if it crossed the setpoint.
        """
        if self.alarm_band_c is None:
            return False
        seg = self._segments[-1]
        start_c = seg.air0_c
        end_c = float(_segment_air_c(seg, self.tau_s, np.array([max(t_s, seg.t0_s)]))[0])
        low_c, high_c = min(start_c, end_c), max(start_c, end_c)
        if low_c <= self._setpoint_c <= high_c:
            return True
        closest_c = min(abs(start_c - self._setpoint_c), abs(end_c - self._setpoint_c))
        return closest_c <= self.alarm_band_c
