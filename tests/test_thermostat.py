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
