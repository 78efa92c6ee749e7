"""The thermostat with hysteresis (TF-14): closed-form switching times and time-freezing clock."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tfcontact.errors import InvalidInput
from tfcontact.scenes.thermostat import (
    OFF,
    TF14,
    ThermostatProblem,
    numerical_switch_intervals,
    physical_time,
    switching_times,
    temperature,
)


def event_located_switches(problem, t_end):
    """Independent reference: the relay integrated with scipy events."""
    t, y, heating, times = 0.0, problem.y0, True, []
    while t < t_end:
        def rhs(_t, z, heating=heating):
            return [-problem.decay * z[0] + (problem.heat if heating else 0.0)]

        def guard(_t, z, heating=heating):
            return z[0] - (problem.y_off if heating else problem.y_on)

        guard.terminal = True
        guard.direction = 1.0 if heating else -1.0
        with np.errstate(under="ignore"):
            sol = solve_ivp(rhs, (t, t_end), [y], rtol=1e-12, atol=1e-12, events=guard)
        t, y = sol.t[-1], sol.y[0, -1]
        if sol.status == 1:
            times.append(t)
            heating = not heating
    return np.array(times)


def test_switching_times_match_event_location():
    times, modes = switching_times(TF14, t_end=4.0)
    assert times[0] == pytest.approx(5 * np.log(35 / 30), abs=1e-14)
    assert modes[0] == OFF and np.all(np.abs(np.diff(modes)) == 1)
    np.testing.assert_allclose(times, event_located_switches(TF14, 4.0), atol=1e-9)


def test_time_freezing_clock():
    starts, ends = numerical_switch_intervals(TF14)
    np.testing.assert_allclose(ends - starts, 2 / TF14.push_gain)
    t_phys = switching_times(TF14, t_end=4.0)[0]
    # numerical time = physical time + the frozen phases already passed
    np.testing.assert_allclose(starts, t_phys[: starts.size] + 0.4 * np.arange(starts.size))
    # at tau = 4 four push phases of 0.4 are complete
    assert physical_time(TF14, 4.0)[0] == pytest.approx(4.0 - 4 * 0.4, abs=1e-14)
    assert physical_time(TF14, starts[1] + 0.1)[0] == pytest.approx(t_phys[1], abs=1e-14)


def test_thermostat_validation():
    with pytest.raises(InvalidInput, match="`y_on` \\(20.0\\) must be below `y_off`"):
        ThermostatProblem(y_on=20.0, y_off=18.0)
    with pytest.raises(InvalidInput, match="the heater never turns off"):
        ThermostatProblem(heat=3.0)


def test_fesd_simulation_reproduces_the_relay():
    from tfcontact.fesd import simulate
    from tfcontact.mpcc import Homotopy, Ipopt, Scholtes
    from tfcontact.scenes.thermostat import time_freezing_system

    system = time_freezing_system(TF14)
    horizon = 2.4  # numerical time: two frozen switches and part of the third phase
    sim = simulate(
        system.pss,
        system.initial_state([TF14.y0], 0.0),
        horizon=horizon,
        n_steps=24,
        n_finite_elements=2,
        relaxation=Scholtes(),
        homotopy=Homotopy(sigma_0=1.0, kappa=0.1, tolerance=1e-9),
        nlp=Ipopt(tol=1e-10),
    )
    clock = sim.x[:, system.clock_index]
    w = sim.x[:, system.memory_index]
    # the physical time at which the memory starts to move (clock frozen from there)
    moving = np.flatnonzero(np.abs(np.diff(w)) > 1e-3)
    starts = [moving[0]] + [b for a, b in zip(moving[:-1], moving[1:], strict=True) if b > a + 1]
    t_exact, modes = switching_times(TF14, t_end=float(clock[-1]))
    assert len(starts) == t_exact.size == 2
    # Radau IIA (s = 2, order 3) with h = 0.05: a few 1e-5 s of drift per switch
    np.testing.assert_allclose(clock[starts], t_exact, atol=1e-4)
    np.testing.assert_allclose(sim.x[starts, 0], [TF14.y_off, TF14.y_on], atol=1e-4)
    # each push phase lasts 2/a of numerical time with the clock frozen
    np.testing.assert_allclose(np.ptp(clock[starts[0]:starts[0] + 8]), 0.0, atol=1e-8)
    # the physical trajectory (frozen pieces dropped) is the relay's, up to the switch
    # timing error (< 1e-4 s) times the slope |y'| < 7 deg C/s
    running = np.concatenate([[True], np.diff(clock) > 1e-6 * np.diff(sim.t)])
    np.testing.assert_allclose(
        sim.x[running, 0], temperature(TF14, clock[running]), atol=7e-4
    )
    # In numerical time the discrete solution lingers near the triple point (psi, w) = (1, 0)
    # (where the push-down vanishes: 0 is in the Filippov set) before the push-up starts,
    # so its clock lags the exact time-freezing clock; it never runs ahead.
    assert clock[-1] <= physical_time(TF14, horizon)[0] + 1e-6
