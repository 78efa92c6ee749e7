"""The time-optimal car with a turbo and hysteresis (PROBLEMS.md TF-13, DESIGN.md section 4.5).

A car on a line, position q [m], velocity v [m/s], fuel L [fuel units], driven by an
acceleration command u [m/s^2], |u| <= u_max. A hybrid automaton with memory w selects
the mode (Avraam 2000; Nurkanovic and Diehl, IEEE CSL 2022, arXiv 2203.11510, section V):

    nominal (w = 0):  q' = v,  v' = u,          L' = P_n
    turbo   (w = 1):  q' = v,  v' = k_turbo u,  L' = P_t

The automaton switches nominal -> turbo when v rises to v_2 = 15 and turbo -> nominal
when v falls to v_1 = 10 (hysteresis: between v_1 and v_2 both modes are possible and
the mode depends on the past). Task: from rest at q = 0 in the nominal mode reach
q = 150, v = 0 in minimum time with v in [0, 25].

This module holds the problem data (`CarProblem`), the closed-form time-optimal solution
of the continuous-time problem (`time_optimal_reference`), and an event-located
high-accuracy simulation of the automaton for piecewise-constant controls
(`simulate_car`), which measures the terminal error E = ||(q(T), v(T)) - (q_goal, v_goal)||
of any method's controls.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from tfcontact.errors import InvalidInput
from tfcontact.ocp import Constraint, OptimalControlProblem
from tfcontact.timefreezing.hysteresis import hysteresis_system
from tfcontact.timefreezing.system import TimeFreezingSystem, with_speed_of_time

NOMINAL = 0
TURBO = 1


@dataclass(frozen=True)
class CarProblem:
    """Data of TF-13 (values of PROBLEMS.md and nosnoc's `car_hysteresis_model_voronoi.m`).

    Args:
        v_turbo_on: v_2 [m/s], the nominal -> turbo threshold (v rising).
        v_turbo_off: v_1 [m/s], the turbo -> nominal threshold (v falling), v_1 < v_2.
        u_max: bound on the acceleration command, |u| <= u_max [m/s^2].
        v_min, v_max: velocity bounds [m/s].
        q_goal, v_goal: terminal position [m] and velocity [m/s].
        turbo_gain: k_turbo, the turbo acceleration is k_turbo u [-].
        fuel_rate_nominal, fuel_rate_turbo: P_n, P_t [fuel/s] (both 1 in the paper's OCP).
        push_gain: a, the gain of the time-freezing push fields (DESIGN.md 4.5) [1/s].
    """

    v_turbo_on: float = 15.0
    v_turbo_off: float = 10.0
    u_max: float = 5.0
    v_min: float = 0.0
    v_max: float = 25.0
    q_goal: float = 150.0
    v_goal: float = 0.0
    turbo_gain: float = 3.0
    fuel_rate_nominal: float = 1.0
    fuel_rate_turbo: float = 1.0
    push_gain: float = 1.0

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not np.isfinite(value):
                raise InvalidInput(f"`{name}` must be finite, got {value}")
        if not self.v_turbo_off < self.v_turbo_on:
            raise InvalidInput(
                f"`v_turbo_off` ({self.v_turbo_off}) must be below `v_turbo_on` "
                f"({self.v_turbo_on}): the hysteresis band is [v_turbo_off, v_turbo_on]"
            )
        if not self.v_min <= self.v_turbo_off and self.v_turbo_on <= self.v_max:
            raise InvalidInput(
                f"the thresholds [{self.v_turbo_off}, {self.v_turbo_on}] must lie inside "
                f"[`v_min`, `v_max`] = [{self.v_min}, {self.v_max}]"
            )
        if self.u_max <= 0:
            raise InvalidInput(f"`u_max` must be positive, got {self.u_max}")
        if self.turbo_gain <= 0:
            raise InvalidInput(f"`turbo_gain` must be positive, got {self.turbo_gain}")
        if self.push_gain <= 0:
            raise InvalidInput(f"`push_gain` must be positive, got {self.push_gain}")
        if not self.v_min <= self.v_goal <= self.v_max:
            raise InvalidInput(
                f"`v_goal` = {self.v_goal} must lie in [`v_min`, `v_max`] = "
                f"[{self.v_min}, {self.v_max}]"
            )

    @property
    def goal(self) -> np.ndarray:
        """(q_goal, v_goal)."""
        return np.array([self.q_goal, self.v_goal])

    def acceleration(self, mode: int, u: float) -> float:
        """v' [m/s^2] in `mode` (NOMINAL or TURBO) under the command u."""
        return u if mode == NOMINAL else self.turbo_gain * u

    def fuel_rate(self, mode: int) -> float:
        """L' [fuel/s] in `mode`."""
        return self.fuel_rate_nominal if mode == NOMINAL else self.fuel_rate_turbo


TF13 = CarProblem()
"""The data of PROBLEMS.md TF-13 (the defaults)."""


def time_freezing_system(problem: CarProblem = TF13) -> TimeFreezingSystem:
    """The car as a time-freezing hysteresis system (DESIGN.md 4.5).

    y = (q, v, L, w, t), u = (u,): nominal f_A = (v, u, P_n), turbo f_B = (v, k u, P_t),
    relay signal v with thresholds (v_1, v_2), push gain a = `problem.push_gain`.
    Built by `tfcontact.timefreezing.hysteresis_system`; add the speed of time with
    `tfcontact.timefreezing.system.with_speed_of_time`.
    """
    x = ca.SX.sym("x", 3)
    u = ca.SX.sym("u")
    f_a = ca.vertcat(x[1], u, problem.fuel_rate_nominal)
    f_b = ca.vertcat(x[1], problem.turbo_gain * u, problem.fuel_rate_turbo)
    return hysteresis_system(
        x,
        u,
        f_a,
        f_b,
        x[1],
        (problem.v_turbo_off, problem.v_turbo_on),
        push_gain=problem.push_gain,
        state_names=("q", "v", "L"),
        control_names=("u",),
    )


def time_optimal_ocp(
    n_intervals: int,
    problem: CarProblem = TF13,
    *,
    numerical_horizon: float = 5.0,
    speed_of_time: tuple[float, float] = (0.1, 100.0),
) -> tuple[TimeFreezingSystem, OptimalControlProblem]:
    """The time-optimal OCP of the time-freezing car with a speed of time per stage.

    min t(T_num) s.t. y' = s F(y, u) theta (the time-freezing PSS with speed of time s),
    |u| <= u_max, s_k in `speed_of_time`, v in [v_min, v_max] at every grid and stage
    point, q(T_num) = q_goal, v(T_num) = v_goal. The physical horizon is free (the
    terminal clock is the cost); the physical control grid is the clock at the stage
    boundaries, not equidistant (nosnoc's stage-wise clock constraint t_k = k T_phys/N
    needs a global variable T_phys, which `OptimalControlProblem` does not have).
    Control guess: u = u_max on the first half of the stages, -u_max after; s = 1.

    Args:
        n_intervals: N control stages.
        problem: the car data.
        numerical_horizon: T_num [s of numerical time].
        speed_of_time: (s_min, s_max) [-], the paper's (0.1, 100).

    Returns:
        (the time-freezing system with speed of time, the `OptimalControlProblem`).
    """
    if not 0 < speed_of_time[0] < speed_of_time[1]:
        raise InvalidInput(f"`speed_of_time` must be (s_min, s_max), 0 < s_min < s_max, "
                           f"got {speed_of_time}")
    system = with_speed_of_time(time_freezing_system(problem))
    y = system.y
    n = n_intervals
    u_guess = np.array([[problem.u_max if k < n / 2 else -problem.u_max, 1.0] for k in range(n)])
    inf = np.inf
    return system, OptimalControlProblem(
        system=system.pss,
        x0=system.initial_state([0.0, 0.0, 0.0], 0.0),
        horizon=numerical_horizon,
        n_intervals=n,
        mayer=y[system.clock_index],
        u_lower=[-problem.u_max, speed_of_time[0]],
        u_upper=[problem.u_max, speed_of_time[1]],
        x_lower=[-inf, problem.v_min, -inf, -inf, -inf],
        x_upper=[inf, problem.v_max, inf, inf, inf],
        terminal=Constraint(ca.vertcat(y[0] - problem.q_goal, y[1] - problem.v_goal)),
        u_guess=u_guess,
    )


@dataclass(frozen=True)
class CarReference:
    """The closed-form time-optimal solution (see `time_optimal_reference`).

    Attributes:
        final_time: T* [s].
        peak_velocity: the largest velocity [m/s] (v_max when the bound is active).
        turbo_on_time, turbo_off_time: physical times [s] of the two mode switches.
        times: a control grid [s] on which the optimal control is piecewise constant.
        controls: the optimal u on each interval of `times` [m/s^2].
    """

    final_time: float
    peak_velocity: float
    turbo_on_time: float
    turbo_off_time: float
    times: np.ndarray
    controls: np.ndarray


def time_optimal_reference(problem: CarProblem = TF13) -> CarReference:
    """Closed-form minimum time of TF-13 (continuous time, switches anywhere).

    Any admissible trajectory has v' <= u_max in the nominal mode and v' <= k u_max in
    turbo; turbo is only reachable by accelerating to v_2 in the nominal mode, and a stop
    at v_goal < v_1 must end in the nominal mode below v_1. The fastest velocity profile is
    therefore: nominal, u = u_max up to v_2; turbo, u = u_max up to the peak v_p (cruise at
    v_max with u = 0 if the peak is cut by v_max); turbo, u = -u_max down to v_1; nominal,
    u = -u_max down to v_goal = 0. With a = k u_max and the remaining distance
    D = q_goal - v_2^2/(2 u_max) - v_1^2/(2 u_max), the peak solves
    (2 v_p^2 - v_2^2 - v_1^2)/(2a) = D. For TF-13: v_p = 43.9 > 25, so the car cruises at
    25 m/s and T* = 3 + 2/3 + 52/15 + 1 + 2 = 152/15 s.

    Raises:
        InvalidInput: if the data leave the regime this formula covers (start from rest,
            v_goal = 0, a goal far enough ahead that the turbo is used).
    """
    p = problem
    if p.v_goal != 0.0 or p.v_min > 0.0:
        raise InvalidInput(
            f"the closed form needs `v_goal` = 0 and `v_min` <= 0, got {p.v_goal}, {p.v_min}"
        )
    a = p.turbo_gain * p.u_max
    d_up = p.v_turbo_on**2 / (2 * p.u_max)
    d_down = p.v_turbo_off**2 / (2 * p.u_max)
    remaining = p.q_goal - d_up - d_down
    d_turbo_min = (p.v_turbo_on**2 - p.v_turbo_off**2) / (2 * a)
    if remaining < d_turbo_min:
        raise InvalidInput(
            f"`q_goal` = {p.q_goal} is too short for the turbo to be used; the closed form "
            f"needs q_goal >= {d_up + d_down + d_turbo_min:.6g}"
        )
    v_peak = np.sqrt((2 * a * remaining + p.v_turbo_on**2 + p.v_turbo_off**2) / 2)
    cruise = 0.0
    if v_peak > p.v_max:
        v_peak = p.v_max
        d_turbo = (2 * v_peak**2 - p.v_turbo_on**2 - p.v_turbo_off**2) / (2 * a)
        cruise = (remaining - d_turbo) / v_peak
    t_on = p.v_turbo_on / p.u_max
    t_peak = t_on + (v_peak - p.v_turbo_on) / a
    t_brake = t_peak + cruise
    t_off = t_brake + (v_peak - p.v_turbo_off) / a
    final = t_off + p.v_turbo_off / p.u_max
    if cruise > 0:
        times = np.array([0.0, t_peak, t_brake, final])
        controls = np.array([p.u_max, 0.0, -p.u_max])
    else:
        times = np.array([0.0, t_peak, final])
        controls = np.array([p.u_max, -p.u_max])
    return CarReference(
        final_time=float(final),
        peak_velocity=float(v_peak),
        turbo_on_time=float(t_on),
        turbo_off_time=float(t_off),
        times=times,
        controls=controls,
    )


@dataclass(frozen=True)
class CarSimulation:
    """Result of `simulate_car`.

    Attributes:
        t: sample times [s], including every event and grid point.
        y: states (q, v, L) at the samples, shape (3, len(t)).
        mode: the mode (NOMINAL/TURBO) on the segment that ends at each sample.
        switch_times: times [s] of the mode switches.
        switch_velocities: v [m/s] at the switches.
        switch_modes: the mode entered at each switch.
        final_mode: the mode at the final time.
        goal: (q_goal, v_goal).
        n_rhs: right-hand-side evaluations (work counter).
    """

    t: np.ndarray
    y: np.ndarray
    mode: np.ndarray
    switch_times: np.ndarray
    switch_velocities: np.ndarray
    switch_modes: np.ndarray
    final_mode: int
    goal: np.ndarray
    n_rhs: int

    @property
    def final_state(self) -> np.ndarray:
        """(q, v, L) at the final time."""
        return self.y[:, -1].copy()

    @property
    def terminal_error(self) -> float:
        """E = ||(q(T), v(T)) - (q_goal, v_goal)||_2 [m, m/s mixed, as in the paper]."""
        return float(np.linalg.norm(self.y[:2, -1] - self.goal))

    @property
    def velocity_range(self) -> tuple[float, float]:
        """(min v, max v) over the trajectory (v is piecewise linear: samples suffice)."""
        return float(self.y[1].min()), float(self.y[1].max())


def _check_controls(controls: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    controls = np.asarray(controls, dtype=float).reshape(-1)
    times = np.asarray(times, dtype=float).reshape(-1)
    if times.size != controls.size + 1:
        raise InvalidInput(
            f"`times` must have one entry more than `controls`: got {times.size} times and "
            f"{controls.size} controls"
        )
    if controls.size == 0:
        raise InvalidInput("`controls` is empty: give at least one control interval")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(controls))):
        raise InvalidInput("`times` and `controls` must be finite")
    if np.any(np.diff(times) <= 0):
        raise InvalidInput(f"`times` must be strictly increasing, got {times}")
    return controls, times


def simulate_car(
    controls: np.ndarray,
    times: np.ndarray,
    problem: CarProblem = TF13,
    *,
    initial_state: tuple[float, float, float] = (0.0, 0.0, 0.0),
    initial_mode: int = NOMINAL,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    max_switches: int = 1000,
) -> CarSimulation:
    """Event-located simulation of the hybrid automaton with hysteresis.

    u(t) = controls[k] on [times[k], times[k+1]). In the nominal mode the event
    v - v_2 = 0 (v rising) switches to turbo; in turbo the event v - v_1 = 0 (v falling)
    switches back. Each segment between grid points and events is integrated by
    scipy's DOP853 with `rtol`/`atol`; events are located by root finding on its dense
    output (to machine precision), the integration restarts in the new mode from the
    event state, so the memory state w is exact.

    Main args:
        controls: u_k [m/s^2], shape (N,).
        times: the control grid t_0 < ... < t_N [s], shape (N + 1,).
        problem: the car data.

    Other args:
        initial_state: (q, v, L) at times[0].
        initial_mode: NOMINAL or TURBO at times[0].
        rtol, atol: integrator tolerances.
        max_switches: guard against chattering input (raises beyond it).

    Returns:
        A `CarSimulation` (final state, switch times and velocities, terminal error).

    Raises:
        InvalidInput: on malformed controls/times or more than `max_switches` switches.
    """
    controls, times = _check_controls(controls, times)
    if initial_mode not in (NOMINAL, TURBO):
        raise InvalidInput(f"`initial_mode` must be NOMINAL (0) or TURBO (1), got {initial_mode}")
    p = problem
    y = np.asarray(initial_state, dtype=float).reshape(3)
    mode = initial_mode
    ts, ys, modes = [times[0]], [y.copy()], [mode]
    sw_t: list[float] = []
    sw_v: list[float] = []
    sw_m: list[int] = []
    n_rhs = 0

    def rhs_for(m: int, u: float):
        acc = p.acceleration(m, u)
        fuel = p.fuel_rate(m)

        def rhs(_t, z):
            return np.array([z[1], acc, fuel])

        return rhs

    def on_event(_t, z):
        return z[1] - p.v_turbo_on

    on_event.terminal = True
    on_event.direction = 1.0

    def off_event(_t, z):
        return z[1] - p.v_turbo_off

    off_event.terminal = True
    off_event.direction = -1.0

    for k, u in enumerate(controls):
        t = times[k]
        t_end = times[k + 1]
        while True:
            # A guard that already holds at the segment start (v = v_2 exactly on a grid
            # point with v rising, say) fires at once: root finding would not see it.
            acc = p.acceleration(mode, u)
            fires_on = mode == NOMINAL and y[1] >= p.v_turbo_on and acc > 0
            fires_off = mode == TURBO and y[1] <= p.v_turbo_off and acc < 0
            if fires_on or fires_off:
                mode = TURBO if fires_on else NOMINAL
                sw_t.append(t)
                sw_v.append(y[1])
                sw_m.append(mode)
            event = on_event if mode == NOMINAL else off_event
            # scipy's minimum step is 10 ulp(t): nextafter(0, inf) underflows at t = 0.
            with np.errstate(under="ignore"):
                sol = solve_ivp(
                    rhs_for(mode, u),
                    (t, t_end),
                    y,
                    method="DOP853",
                    rtol=rtol,
                    atol=atol,
                    events=event,
                )
            n_rhs += sol.nfev
            if sol.status == -1:
                raise InvalidInput(f"the integrator failed on [{t}, {t_end}]: {sol.message}")
            t = float(sol.t[-1])
            y = sol.y[:, -1].copy()
            ts.append(t)
            ys.append(y.copy())
            modes.append(mode)
            if sol.status == 1:  # a terminal event: switch and go on from the event state
                mode = TURBO if mode == NOMINAL else NOMINAL
                sw_t.append(t)
                sw_v.append(y[1])
                sw_m.append(mode)
                if len(sw_t) > max_switches:
                    raise InvalidInput(
                        f"more than `max_switches` = {max_switches} mode switches; "
                        "the controls chatter around a threshold"
                    )
                if t < t_end:
                    continue
            break
        ts[-1] = t_end  # the last segment ends exactly on the grid point
    return CarSimulation(
        t=np.array(ts),
        y=np.array(ys).T,
        mode=np.array(modes, dtype=int),
        switch_times=np.array(sw_t),
        switch_velocities=np.array(sw_v),
        switch_modes=np.array(sw_m, dtype=int),
        final_mode=int(mode),
        goal=p.goal,
        n_rhs=n_rhs,
    )
