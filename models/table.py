"""Rate-table physics: an acceleration-limited rate servo with an interlock.

A calibration measures a gyro against the table's rate, so the simulated
table must move the way a real one does: it ramps toward a new demand at its
acceleration limit (never jumps), refuses demands beyond its rate limit, and
stops on its own when the interlock opens. The angle is the exact integral of
that piecewise-constant-acceleration profile, so revolutions counted over an
overnight run are exact rather than the sum of small-step errors.

The motion is kept as a short history of *segments*: each command starts a
segment (time, rate, angle, target rate, acceleration). Any time at or after
the oldest kept segment evaluates in closed form, so a query hours later costs
the same as one a millisecond later, and the simulated gyro can ask for the
table rate over a whole block of frame times at once (including times just
after "now", which extrapolate the current profile).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from gyrocal.models.clock import Clock
from gyrocal.models.sim_state import SIM_HISTORY_S, decode, encode

MODE_OFF = "off"
MODE_RATE = "rate"
MODE_SYNTHESIS = "synthesis"
MODE_POSITION = "position"


class TableLimitError(ValueError):
    """A demand or limit outside what the table can do; the table's state is unchanged."""


class TableInterlockError(RuntimeError):
    """Motion was commanded while the interlock is open (a safety condition)."""


class TableModeError(RuntimeError):
    """A demand arrived in a mode that does not accept it (e.g. a rate demand while off)."""


@dataclass(frozen=True)
class _Segment:
    """Motion from ``t0_s``: rate ramps from ``rate0_dps`` to ``target_dps`` at ``accel_dps2``."""

    t0_s: float
    rate0_dps: float
    angle0_deg: float
    target_dps: float
    accel_dps2: float

    @property
    def ramp_s(self) -> float:
        return abs(self.target_dps - self.rate0_dps) / self.accel_dps2

    def rate_dps(self, dt_s: np.ndarray) -> np.ndarray:
        sign = np.sign(self.target_dps - self.rate0_dps)
        ramping = self.rate0_dps + sign * self.accel_dps2 * dt_s
        return np.where(dt_s >= self.ramp_s, self.target_dps, ramping)

    def angle_deg(self, dt_s: np.ndarray) -> np.ndarray:
        sign = np.sign(self.target_dps - self.rate0_dps)
        ramp_dt_s = np.minimum(dt_s, self.ramp_s)
        ramp_angle = self.rate0_dps * ramp_dt_s + 0.5 * sign * self.accel_dps2 * ramp_dt_s**2
        return self.angle0_deg + ramp_angle + self.target_dps * (dt_s - ramp_dt_s)


@dataclass(frozen=True)
class _SineSegment:
    """Synthesis mode from ``t0_s`` (TM-8004 §4.3.4, §4.7.6): the position is a sinusoid
    of peak displacement ``amplitude_deg`` at ``freq_hz`` with initial phase ``phase_deg``,
    centred so the angle is continuous where it starts. The rate is its exact derivative,
    so a gyro on the table and the table's readback see the same sinusoid. The amplitude
    slew of a real controller (Configure:Oscillator, §4.2.19) is not modelled: the motion
    is at its steady amplitude from the first instant.
    """

    t0_s: float
    angle0_deg: float
    amplitude_deg: float
    freq_hz: float
    phase_deg: float
    ramp_s: float = 0.0         # no ramp: settle_time_s is the segment's start
    target_dps: float = 0.0     # the rate the servo returns to when synthesis ends

    @property
    def peak_rate_dps(self) -> float:
        return abs(self.amplitude_deg) * 2.0 * np.pi * self.freq_hz

    def _arg(self, dt_s: np.ndarray) -> np.ndarray:
        return 2.0 * np.pi * self.freq_hz * dt_s + np.radians(self.phase_deg)

    def rate_dps(self, dt_s: np.ndarray) -> np.ndarray:
        return self.amplitude_deg * 2.0 * np.pi * self.freq_hz * np.cos(self._arg(dt_s))

    def angle_deg(self, dt_s: np.ndarray) -> np.ndarray:
        start = np.sin(np.radians(self.phase_deg))
        return self.angle0_deg + self.amplitude_deg * (np.sin(self._arg(dt_s)) - start)


def position_move(t0_s: float, angle0_deg: float, target_deg: float, max_rate_dps: float,
                  accel_dps2: float) -> list[_Segment]:
    """A move from rest at ``angle0_deg`` to rest at ``target_deg``: the fastest profile the
    limits allow (accelerate, cruise at ``max_rate_dps``, decelerate; a triangle when the
    move is too short to reach it), as two segments, the second starting in the future.

    Kept apart from the rate servo (position mode is the indexing head of the tilt test).
    """
    distance = float(target_deg) - float(angle0_deg)
    if distance == 0.0:
        return [_Segment(t0_s, 0.0, angle0_deg, 0.0, accel_dps2)]
    sign = 1.0 if distance > 0 else -1.0
    span = abs(distance)
    peak_dps = min(max_rate_dps, float(np.sqrt(span * accel_dps2)))
    # time from the start to the beginning of the deceleration: the ramp up, then the cruise
    cruise_s = (span - peak_dps**2 / accel_dps2) / peak_dps
    start_decel_s = peak_dps / accel_dps2 + max(cruise_s, 0.0)
    up = _Segment(t0_s, 0.0, angle0_deg, sign * peak_dps, accel_dps2)
    down_angle = float(up.angle_deg(np.asarray(start_decel_s)))
    return [up, _Segment(t0_s + start_decel_s, sign * peak_dps, down_angle, 0.0, accel_dps2)]


class TablePhysics:
    """One rate-table axis driven by a shared clock.

    Modes: ``off`` (the servo brings the table to rest at the acceleration
    limit and holds it there) and ``rate`` (the table follows the demanded
    rate). Opening the interlock drops the table to ``off``: it decelerates to
    rest and refuses motion until the interlock is closed *and* rate mode is
    entered again, so a table never restarts by itself.

    ``rate_dps``/``angle_deg`` are the true motion (what a gyro on the table
    senses); ``read_rate_dps`` adds the readback noise of the table's encoder
    electronics. Thread-safe: the simulated SCPI server calls it from several
    connection threads.
    """

    def __init__(
        self,
        clock: Clock,
        max_rate_dps: float = 1000.0,
        max_accel_dps2: float = 500.0,
        rate_noise_dps: float = 0.0,
        seed: int | None = None,
        history_segments: int = 4096,
    ) -> None:
        if not max_rate_dps > 0 or not max_accel_dps2 > 0:
            raise ValueError(
                f"table limits must be > 0, got max_rate_dps={max_rate_dps!r}, "
                f"max_accel_dps2={max_accel_dps2!r}"
            )
        if rate_noise_dps < 0:
            raise ValueError(f"rate_noise_dps must be >= 0, got {rate_noise_dps!r}")
        self.clock = clock
        self.max_rate_dps = float(max_rate_dps)
        self.max_accel_dps2 = float(max_accel_dps2)
        self.rate_noise_dps = float(rate_noise_dps)
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._history_segments = int(history_segments)
        self._mode = MODE_OFF
        self._demand_dps = 0.0
        self._accel_limit_dps2 = self.max_accel_dps2
        self._interlock_closed = False
        self._segments: list[_Segment | _SineSegment] = [
            _Segment(clock.now_s(), 0.0, 0.0, 0.0, self.max_accel_dps2)
        ]
        self._starts_s: list[float] = [self._segments[0].t0_s]

    # ----- state --------------------------------------------------------------------------

    @property
    def mode(self) -> str:
        return self._mode

    @property
    def demand_dps(self) -> float:
        return self._demand_dps

    @property
    def accel_limit_dps2(self) -> float:
        return self._accel_limit_dps2

    @property
    def interlock_closed(self) -> bool:
        return self._interlock_closed

    def settle_time_s(self) -> float:
        """Clock time at which the current profile reaches its target rate."""
        with self._lock:
            last = self._segments[-1]
            return last.t0_s + last.ramp_s

    # ----- commands -----------------------------------------------------------------------

    def close_interlock(self) -> None:
        with self._lock:
            self._interlock_closed = True

    def open_interlock(self) -> None:
        """The safety chain opened: drop to off and stop at the acceleration limit."""
        with self._lock:
            self._interlock_closed = False
            self._mode = MODE_OFF
            self._demand_dps = 0.0
            self._retarget(0.0)

    def set_mode_rate(self) -> None:
        with self._lock:
            if not self._interlock_closed:
                raise TableInterlockError("rate mode refused: interlock open")
            if self._mode != MODE_RATE:
                self._mode = MODE_RATE
                self._demand_dps = 0.0
                self._retarget(0.0)

    def set_mode_position(self) -> None:
        """Position mode (the indexing head): the table holds its angle until a position demand."""
        with self._lock:
            if not self._interlock_closed:
                raise TableInterlockError("position mode refused: interlock open")
            if self._mode != MODE_POSITION:
                self._mode = MODE_POSITION
                self._demand_dps = 0.0
                self._retarget(0.0)

    def set_position_demand_deg(self, position_deg: float) -> None:
        """Move to ``position_deg`` (the readout's 0-360 frame, the shorter way round) at the
        rate and acceleration limits. Accepted at rest only (the run waits for each move)."""
        position_deg = float(position_deg)
        with self._lock:
            if not np.isfinite(position_deg):
                raise TableLimitError(f"position demand {position_deg!r} deg is not a number")
            if not self._interlock_closed:
                raise TableInterlockError("position demand refused: interlock open")
            if self._mode != MODE_POSITION:
                raise TableModeError(f"position demand refused: table in mode {self._mode!r}")
            now_s = max(self.clock.now_s(), self._segments[-1].t0_s)
            if now_s < self.settle_time_s() or float(self.rate_dps(now_s)) != 0.0:
                raise TableModeError("position demand refused: the table is still moving")
            angle0 = float(self.angle_deg(now_s))
            step = (position_deg - angle0 + 180.0) % 360.0 - 180.0
            for segment in position_move(now_s, angle0, angle0 + step, self.max_rate_dps,
                                         self._accel_limit_dps2):
                self._push(segment)

    def set_mode_off(self) -> None:
        """Servo to rest at the acceleration limit (always allowed: it is the safe state)."""
        with self._lock:
            self._mode = MODE_OFF
            self._demand_dps = 0.0
            self._retarget(0.0)

    def set_rate_demand_dps(self, rate_dps: float) -> None:
        rate_dps = float(rate_dps)
        with self._lock:
            if not np.isfinite(rate_dps) or abs(rate_dps) > self.max_rate_dps:
                raise TableLimitError(
                    f"rate demand {rate_dps!r} deg/s outside +/-{self.max_rate_dps:g} deg/s"
                )
            if not self._interlock_closed:
                raise TableInterlockError("rate demand refused: interlock open")
            if self._mode != MODE_RATE:
                raise TableModeError(f"rate demand refused: table in mode {self._mode!r}")
            self._demand_dps = rate_dps
            self._retarget(rate_dps)

    def set_accel_limit_dps2(self, accel_dps2: float) -> None:
        accel_dps2 = float(accel_dps2)
        with self._lock:
            if not np.isfinite(accel_dps2) or not 0 < accel_dps2 <= self.max_accel_dps2:
                raise TableLimitError(
                    f"acceleration limit {accel_dps2!r} deg/s^2 outside "
                    f"(0, {self.max_accel_dps2:g}] deg/s^2"
                )
            self._accel_limit_dps2 = accel_dps2
            if self._mode != MODE_SYNTHESIS:
                self._retarget(self._segments[-1].target_dps)

    def set_mode_synthesis(self, amplitude_deg: float, freq_hz: float, phase_deg: float) -> None:
        """Start the sinusoid (TM-8004 §4.7.6) from rest; refused beyond the table's limits.

        The sinusoid's peak rate 2πfA and peak acceleration (2πf)²A must be within the
        table's rate and acceleration limits (the physical ones: synthesis bypasses the
        rate-mode profiler's limit). Entered only from rest: a real controller is taken
        there from position mode, whose demand is the centre of the motion.
        """
        amplitude_deg, freq_hz, phase_deg = float(amplitude_deg), float(freq_hz), float(phase_deg)
        with self._lock:
            if not self._interlock_closed:
                raise TableInterlockError("synthesis mode refused: interlock open")
            if not (np.isfinite(amplitude_deg) and np.isfinite(freq_hz) and freq_hz > 0
                    and np.isfinite(phase_deg)):
                raise TableLimitError(f"oscillator ({amplitude_deg!r} deg, {freq_hz!r} Hz, "
                                      f"{phase_deg!r} deg) is not a sinusoid")
            omega = 2.0 * np.pi * freq_hz
            peak_rate_dps, peak_accel_dps2 = abs(amplitude_deg) * omega, abs(amplitude_deg) * omega**2
            if peak_rate_dps > self.max_rate_dps or peak_accel_dps2 > self.max_accel_dps2:
                raise TableLimitError(
                    f"sinusoid peaks at {peak_rate_dps:.6g} deg/s and {peak_accel_dps2:.6g} "
                    f"deg/s^2, beyond {self.max_rate_dps:g} deg/s or {self.max_accel_dps2:g} deg/s^2")
            now_s = max(self.clock.now_s(), self._segments[-1].t0_s)
            if abs(float(self.rate_dps(now_s))) > 1e-9:
                raise TableModeError("synthesis mode refused: the table is not at rest")
            segment = _SineSegment(now_s, float(self.angle_deg(now_s)), amplitude_deg,
                                   freq_hz, phase_deg)
            self._mode = MODE_SYNTHESIS
            self._demand_dps = 0.0
            self._push(segment)

    # ----- motion queries -----------------------------------------------------------------

    def rate_dps(self, t_s: float | np.ndarray | None = None) -> float | np.ndarray:
        """True table rate at ``t_s`` (default: the clock's now); arrays evaluate per element."""
        return self._evaluate(t_s, rate=True)

    def angle_deg(self, t_s: float | np.ndarray | None = None) -> float | np.ndarray:
        """Unwrapped table angle (∫rate dt since the session start), in degrees."""
        return self._evaluate(t_s, rate=False)

    def position_deg(self) -> float:
        """Angle now, wrapped to [0, 360) as a table's position readout shows it."""
        return float(np.mod(self.angle_deg(), 360.0))

    def revolutions(self, t_s: float | None = None) -> int:
        """Whole signed revolutions since the session start (truncated toward zero)."""
        return int(float(self.angle_deg(t_s)) / 360.0)

    def reseed(self, seed: np.random.SeedSequence) -> None:
        """Measurement noise drawn from ``seed`` from now on (a dry run's attempt)."""
        self._rng = np.random.default_rng(seed)

    def sim_state(self) -> dict:
        """What a resumed dry run restores (``models/sim_state.py``): mode, demand, limits,
        interlock, readback noise stream and the motion of the last ``SIM_HISTORY_S``."""
        with self._lock:
            since_s = self.clock.now_s() - SIM_HISTORY_S
            first = max((i for i, t0 in enumerate(self._starts_s) if t0 <= since_s), default=0)
            return {"rng": encode(self._rng), "mode": self._mode, "demand_dps": self._demand_dps,
                    "accel_limit_dps2": self._accel_limit_dps2,
                    "interlock_closed": self._interlock_closed,
                    "segments": encode(self._segments[first:])}

    def restore_sim_state(self, state: dict) -> None:
        with self._lock:
            self._rng = decode(state["rng"], self._rng)
            self._mode = str(state["mode"])
            self._demand_dps = float(state["demand_dps"])
            self._accel_limit_dps2 = float(state["accel_limit_dps2"])
            self._interlock_closed = bool(state["interlock_closed"])
            self._segments = list(decode(state["segments"]))
            self._starts_s = [segment.t0_s for segment in self._segments]

    def read_rate_dps(self) -> float:
        """Rate readback now: the true rate plus the encoder electronics' noise."""
        with self._lock:
            noise_dps = self._rng.normal(0.0, self.rate_noise_dps) if self.rate_noise_dps else 0.0
            return float(self.rate_dps()) + float(noise_dps)

    # ----- internals ----------------------------------------------------------------------

    def _retarget(self, target_dps: float) -> None:
        """Start a new segment now, from the current motion, toward ``target_dps``.

        A position move's planned future segment is dropped first: a new command (an
        interlock opening mid-move) takes over from the motion as it is now.
        """
        now_s = self.clock.now_s()
        while len(self._segments) > 1 and self._segments[-1].t0_s > now_s:
            self._segments.pop()
            self._starts_s.pop()
        now_s = max(now_s, self._segments[-1].t0_s)
        last = self._segments[-1]
        dt_s = np.asarray(now_s - last.t0_s)
        segment = _Segment(
            now_s,
            float(last.rate_dps(dt_s)),
            float(last.angle_deg(dt_s)),
            float(target_dps),
            self._accel_limit_dps2,
        )
        self._push(segment)

    def _push(self, segment: _Segment | _SineSegment) -> None:
        """Make ``segment`` the current one (replacing one that starts at the same time)."""
        if segment.t0_s == self._segments[-1].t0_s:
            self._segments[-1] = segment
        else:
            self._segments.append(segment)
            self._starts_s.append(segment.t0_s)
        if len(self._segments) > self._history_segments:
            del self._segments[0]
            del self._starts_s[0]

    def _evaluate(self, t_s: float | np.ndarray | None, rate: bool) -> float | np.ndarray:
        scalar = t_s is None or np.ndim(t_s) == 0
        with self._lock:
            times_s = np.atleast_1d(
                np.asarray(self.clock.now_s() if t_s is None else t_s, dtype=float)
            )
            oldest_s = self._starts_s[0]
            if times_s.size and float(times_s.min()) < oldest_s:
                raise ValueError(
                    f"table motion asked for t={float(times_s.min())!r} s, before the oldest "
                    f"kept segment at {oldest_s!r} s"
                )
            if times_s.size and float(times_s.min()) >= self._starts_s[-1]:
                # The usual case: now, or a block just after it, on the current segment.
                last = self._segments[-1]
                dt_s = times_s - last.t0_s
                out = last.rate_dps(dt_s) if rate else last.angle_deg(dt_s)
                return float(out[0]) if scalar else out
            out = np.empty_like(times_s)
            index = np.searchsorted(self._starts_s, times_s, side="right") - 1
            for i in np.unique(index):
                seg = self._segments[i]
                mask = index == i
                dt_s = times_s[mask] - seg.t0_s
                out[mask] = seg.rate_dps(dt_s) if rate else seg.angle_deg(dt_s)
        return float(out[0]) if scalar else out


__all__ = [
    "MODE_OFF",
    "MODE_POSITION",
    "MODE_RATE",
    "MODE_SYNTHESIS",
    "TableInterlockError",
    "TableLimitError",
    "TableModeError",
    "TablePhysics",
    "position_move",
]
