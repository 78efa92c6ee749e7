"""The thermostat with hysteresis (PROBLEMS.md TF-14, DESIGN.md section 4.5).

A room temperature y [deg C] with a heater controlled by a hysteresis relay
(Nurkanovic and Diehl, IEEE CSL 2022, arXiv 2203.11510; nosnoc's
`temp_control_model_voronoi.m`):

    heater on  (w = 0):  y' = -lambda y + p_heat
    heater off (w = 1):  y' = -lambda y

The heater turns off when y rises to y_2 = 20 and on again when y falls to y_1 = 18;
y(0) = 15 with the heater on. Both modes are linear, so the switching times have a
closed form (`switching_times`), and so does the time-freezing solution in numerical
time: each switch is a frozen push phase of numerical length 2/a at psi = 1 or psi = 0,
where the push speed is a psi^2/(1 + psi^2) = a/2 (`numerical_switch_intervals`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.timefreezing.hysteresis import hysteresis_system
from tfcontact.timefreezing.system import TimeFreezingSystem

HEATING = 0
OFF = 1


@dataclass(frozen=True)
class ThermostatProblem:
    """Data of TF-14.

    Args:
        decay: lambda [1/s], y' = -lambda y (+ p_heat when heating).
        heat: p_heat [deg C/s].
        y_on: y_1 [deg C], the heater turns on when y falls to it.
        y_off: y_2 [deg C], the heater turns off when y rises to it.
        y0: initial temperature [deg C] (heater on).
        push_gain: a, the gain of the time-freezing push fields [1/s].
        horizon: numerical simulation horizon T_sim [s of numerical time].
        n_steps: N_sim, simulation steps.
    """

    decay: float = 0.2
    heat: float = 10.0
    y_on: float = 18.0
    y_off: float = 20.0
    y0: float = 15.0
    push_gain: float = 5.0
    horizon: float = 4.0
    n_steps: int = 40

    def __post_init__(self) -> None:
        if not self.y_on < self.y_off:
            raise InvalidInput(
                f"`y_on` ({self.y_on}) must be below `y_off` ({self.y_off}): "
                "the hysteresis band is [y_on, y_off]"
            )
        if not (self.decay > 0 and self.heat > 0):
            raise InvalidInput(
                f"`decay` and `heat` must be positive, got {self.decay}, {self.heat}"
            )
        if not self.heat / self.decay > self.y_off:
            raise InvalidInput(
                f"the heater's steady state heat/decay = {self.heat / self.decay} must exceed "
                f"`y_off` = {self.y_off}, or the heater never turns off"
            )
        if not self.y0 < self.y_off:
            raise InvalidInput(f"`y0` = {self.y0} must be below `y_off` = {self.y_off}")
        if self.push_gain <= 0:
            raise InvalidInput(f"`push_gain` must be positive, got {self.push_gain}")
        if self.horizon <= 0 or self.n_steps < 1:
            raise InvalidInput(
                f"need `horizon` > 0 and `n_steps` >= 1, got {self.horizon}, {self.n_steps}"
            )

    def psi(self, y: float | np.ndarray) -> float | np.ndarray:
        """The normalised hysteresis variable psi = (y - y_1)/(y_2 - y_1)."""
        return (y - self.y_on) / (self.y_off - self.y_on)

    @property
    def push_duration(self) -> float:
        """Numerical time [s] of one frozen push phase: 1/(a psi^2/(1+psi^2)) at psi = 1."""
        return 2.0 / self.push_gain


TF14 = ThermostatProblem()
"""The data of PROBLEMS.md TF-14 (the defaults)."""


def time_freezing_system(problem: ThermostatProblem = TF14) -> TimeFreezingSystem:
    """The thermostat as a time-freezing hysteresis system (DESIGN.md 4.5).

    y = (y, w, t), no control: mode A (w = 0, heating) y' = -lambda y + p_heat,
    mode B (w = 1, off) y' = -lambda y; the relay watches y with thresholds (y_1, y_2).
    """
    y = ca.SX.sym("y")
    return hysteresis_system(
        y,
        ca.SX(0, 1),
        -problem.decay * y + problem.heat,
        -problem.decay * y,
        y,
        (problem.y_on, problem.y_off),
        push_gain=problem.push_gain,
        state_names=("y",),
    )


def switching_times(
    problem: ThermostatProblem = TF14, t_end: float = 10.0
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form physical switching times of the relay up to t_end.

    Heating from y_a: y(t) = h/l + (y_a - h/l) e^{-l t} reaches y_2 after
    (1/l) ln((h/l - y_a)/(h/l - y_2)); cooling from y_2 reaches y_1 after (1/l) ln(y_2/y_1).

    Returns:
        (times [s], modes entered), both of shape (n_switches,).
    """
    p = problem
    steady = p.heat / p.decay
    t, y, mode = 0.0, p.y0, HEATING
    times, modes = [], []
    while True:
        if mode == HEATING:
            dt = np.log((steady - y) / (steady - p.y_off)) / p.decay
            y, mode = p.y_off, OFF
        else:
            dt = np.log(y / p.y_on) / p.decay if p.y_on > 0 else np.inf
            y, mode = p.y_on, HEATING
        if t + dt > t_end:
            break
        t += dt
        times.append(t)
        modes.append(mode)
    return np.array(times), np.array(modes, dtype=int)


def temperature(problem: ThermostatProblem, t: float | np.ndarray) -> np.ndarray:
    """The exact relay trajectory y(t) [deg C] at physical times t >= 0 (closed form)."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    times, modes = switching_times(problem, t_end=float(t.max()))
    starts = np.concatenate([[0.0], times])
    start_modes = np.concatenate([[HEATING], modes])
    start_values = np.array(
        [problem.y0] + [problem.y_off if m == OFF else problem.y_on for m in modes]
    )
    k = np.searchsorted(starts, t, side="right") - 1
    steady = np.where(start_modes[k] == HEATING, problem.heat / problem.decay, 0.0)
    return steady + (start_values[k] - steady) * np.exp(-problem.decay * (t - starts[k]))


def numerical_switch_intervals(
    problem: ThermostatProblem = TF14, tau_end: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Where the time-freezing solution is frozen, in numerical time tau.

    The k-th switch (physical time t_k) starts at tau_k = t_k + k * 2/a and lasts 2/a.

    Returns:
        (starts, ends) [s of numerical time] of the frozen phases that start before tau_end
        (default: the problem's horizon).
    """
    tau_end = problem.horizon if tau_end is None else tau_end
    times, _ = switching_times(problem, t_end=tau_end)
    starts = times + problem.push_duration * np.arange(times.size)
    starts = starts[starts < tau_end]
    return starts, starts + problem.push_duration


def physical_time(problem: ThermostatProblem, tau: float | np.ndarray) -> np.ndarray:
    """The clock t(tau) of the exact time-freezing solution [s]: tau minus the frozen time."""
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    starts, ends = numerical_switch_intervals(problem, tau_end=float(tau.max()) + 1e-12)
    frozen = np.zeros_like(tau)
    for a, b in zip(starts, ends, strict=True):
        frozen += np.clip(tau - a, 0.0, b - a)
    return tau - frozen
