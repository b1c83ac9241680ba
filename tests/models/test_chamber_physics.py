"""ChamberPhysics against independent references: an ODE solver, a curve fit, statistics."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import curve_fit

from gyrocal.models.chamber import ChamberPhysics
from gyrocal.models.clock import SimClock

pytestmark = pytest.mark.timeout(30)

HEAT_C_PER_MIN = 5.0
COOL_C_PER_MIN = 3.5
TAU_S = 300.0


def make_physics(clock, **overrides):
    params = dict(
        ambient_c=22.0, tau_s=TAU_S, max_heat_c_per_min=HEAT_C_PER_MIN,
        max_cool_c_per_min=COOL_C_PER_MIN, min_setpoint_c=-70.0, max_setpoint_c=180.0,
        noise_c=0.0, seed=7,
    )
    params.update(overrides)
    return ChamberPhysics(clock, **params)


def ode_reference(profile, t_end_s, start_c=22.0, heat=HEAT_C_PER_MIN, cool=COOL_C_PER_MIN, target_of=None):
    """Integrate dT/dt = clip((SP - T)/tau, -cool, +heat) numerically through a setpoint profile."""
    target_of = target_of or (lambda sp: sp)
    times = [t for t, _ in profile] + [t_end_s]
    temp_c = start_c
    samples = {}
    for (t0, sp), t1 in zip(profile, times[1:], strict=False):
        target = target_of(sp)

        def rhs(_t, y, target=target):
            return [np.clip((target - y[0]) / TAU_S, -cool / 60.0, heat / 60.0)]

        sol = solve_ivp(rhs, (t0, t1), [temp_c], max_step=5.0, rtol=1e-9, atol=1e-9, dense_output=True)
        samples[(t0, t1)] = sol.sol
        temp_c = float(sol.y[0, -1])
    return temp_c, samples


def test_heating_and_cooling_slopes_never_exceed_the_ramp_limits():
    clock = SimClock()
    physics = make_physics(clock)
    physics.set_setpoint(150.0)
    t_s = np.linspace(0, 4 * 3600, 20001)
    air_c = physics.air_temperature_c(t_s)
    slope_c_per_min = np.diff(air_c) / np.diff(t_s) * 60
    assert slope_c_per_min.max() <= HEAT_C_PER_MIN + 1e-9
    # far from the setpoint the chamber ramps at exactly the limit
    assert physics.true_temperature_c(600.0) == pytest.approx(22.0 + HEAT_C_PER_MIN * 10, abs=1e-6)

    clock.advance_to(4 * 3600)
    physics.set_setpoint(-60.0)
    t_s = np.linspace(4 * 3600, 10 * 3600, 20001)
    slope_c_per_min = np.diff(physics.air_temperature_c(t_s)) / np.diff(t_s) * 60
    assert slope_c_per_min.min() >= -COOL_C_PER_MIN - 1e-9
    assert slope_c_per_min.min() == pytest.approx(-COOL_C_PER_MIN, rel=1e-6)


def test_time_constant_is_recovered_from_a_noisy_small_step():
    clock = SimClock()
    physics = make_physics(clock, noise_c=0.05, seed=3)
    physics.set_setpoint(32.0)          # 10 °C: below r*tau = 25 °C, so purely exponential
    t_s = np.arange(0.0, 2400.0, 5.0)
    measured_c = np.array([physics.temperature_c(t) for t in t_s])

    def step(t, tau, final, start):
        return final + (start - final) * np.exp(-t / tau)

    (tau_fit, final_fit, start_fit), _ = curve_fit(step, t_s, measured_c, p0=(100.0, 30.0, 20.0))
    assert tau_fit == pytest.approx(TAU_S, rel=0.02)
    assert final_fit == pytest.approx(32.0, abs=0.02)
    assert start_fit == pytest.approx(22.0, abs=0.05)


def test_closed_form_matches_a_numerical_integration_through_a_profile():
    clock = SimClock()
    physics = make_physics(clock)
    profile = [(0.0, 85.0), (7200.0, -40.0), (18000.0, 25.0)]
    for t_s, sp_c in profile:
        clock.advance_to(t_s)
        physics.set_setpoint(sp_c)
    _, pieces = ode_reference(profile, 8 * 3600)
    for (t0, t1), dense in pieces.items():
        grid_s = np.linspace(t0, t1, 400)
        np.testing.assert_allclose(physics.air_temperature_c(grid_s), dense(grid_s)[0], atol=2e-3)


def test_eight_hours_in_one_jump_equals_many_small_steps():
    profile = [(0.0, 85.0), (7200.0, -40.0), (18000.0, 25.0)]
    end_s = 8 * 3600.0

    jump_clock = SimClock()
    jumped = make_physics(jump_clock)
    for t_s, sp_c in profile:
        jump_clock.advance_to(t_s)
        jumped.set_setpoint(sp_c)
    jump_clock.advance_to(end_s)
    jumped_end_c = jumped.temperature_c()

    step_clock = SimClock()
    stepped = make_physics(step_clock)
    pending = list(profile)
    trace_c = []
    for t_s in np.arange(0.0, end_s + 1.0, 10.0):
        step_clock.advance_to(t_s)
        while pending and pending[0][0] <= t_s:
            stepped.set_setpoint(pending.pop(0)[1])
        trace_c.append(stepped.temperature_c())
    assert jumped_end_c == pytest.approx(trace_c[-1], abs=1e-9)
    reference_end_c, _ = ode_reference(profile, end_s)
    assert jumped_end_c == pytest.approx(reference_end_c, abs=2e-3)
    assert jumped_end_c == pytest.approx(25.0, abs=1e-3)


def test_setpoints_outside_the_range_are_refused_and_leave_the_setpoint_alone():
    physics = make_physics(SimClock())
    physics.set_setpoint(40.0)
    for bad_c in (180.1, -70.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="outside the chamber range"):
            physics.set_setpoint(bad_c)
    assert physics.setpoint_c == 40.0
    physics.set_setpoint(180.0)   # the limits themselves are allowed
    physics.set_setpoint(-70.0)


def test_measurement_noise_has_the_configured_level():
    clock = SimClock()
    physics = make_physics(clock, noise_c=0.08, seed=11)
    clock.advance_to(10.0)   # at ambient, settled
    readings_c = np.array([physics.temperature_c() for _ in range(4000)])
    assert readings_c.std(ddof=1) == pytest.approx(0.08, rel=0.06)
    assert abs(readings_c.mean() - 22.0) < 4 * 0.08 / np.sqrt(readings_c.size)
    assert physics.true_temperature_c() == 22.0


def test_vectorised_air_temperature_matches_scalar_queries_and_refuses_the_past():
    clock = SimClock(start_s=100.0)
    physics = make_physics(clock)
    physics.set_setpoint(60.0)
    t_s = np.linspace(100.0, 1100.0, 57)
    vector_c = physics.air_temperature_c(t_s)
    assert vector_c == pytest.approx([physics.true_temperature_c(t) for t in t_s], abs=0)
    with pytest.raises(ValueError, match="history starts"):
        physics.air_temperature_c(np.array([50.0]))


def test_stuck_chamber_stalls_short_of_the_setpoint():
    clock = SimClock()
    physics = make_physics(clock, stuck_capacity=0.5)
    physics.stuck = True
    physics.set_setpoint(100.0)
    clock.advance_to(8 * 3600)
    stalled_c = physics.temperature_c()
    clock.advance_to(10 * 3600)
    assert physics.temperature_c() == pytest.approx(stalled_c, abs=1e-6)   # stalled, not still creeping
    assert stalled_c == pytest.approx(22.0 + 0.5 * (100.0 - 22.0), abs=1e-3)
    physics.stuck = False
    clock.advance_to(14 * 3600)
    assert physics.temperature_c() == pytest.approx(100.0, abs=1e-3)


def test_process_alarm_when_the_air_leaves_the_allowed_range():
    clock = SimClock()
    physics = make_physics(clock, alarm_high_c=50.0)
    physics.set_setpoint(60.0)
    assert not physics.alarm_state().active
    clock.advance_to(2 * 3600)
    state = physics.alarm_state()
    assert state.active and "process high" in state.detail


def test_deviation_alarm_is_blocked_during_the_ramp_and_fires_when_the_air_drifts():
    clock = SimClock()
    physics = make_physics(clock, alarm_band_c=2.0)
    physics.set_setpoint(80.0)
    for t_s in (60.0, 600.0, 1200.0):         # ramping, far from the setpoint: blocked
        clock.advance_to(t_s)
        assert not physics.alarm_state().active
    clock.advance_to(3 * 3600)                   # settled inside the band: armed, quiet
    assert not physics.alarm_state().active
    physics.stuck = True                         # heater loses power: air sags away
    clock.advance_to(4 * 3600)
    state = physics.alarm_state()
    assert state.active and "deviation" in state.detail
