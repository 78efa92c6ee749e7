"""Time-freezing for a two-mode hysteresis (hybrid automaton with memory w).

DESIGN.md 4.5, PROBLEMS.md 0.5; Nurkanovic, Diehl, "Continuous optimization for control
of hybrid systems with hysteresis via time-freezing", IEEE CSL 2022 (arXiv 2203.11510).

The hybrid system x' = (1 - w) f_A(x, u) + w f_B(x, u), w in {0, 1}, with w: 0 -> 1 when
the signal y(x) rises to the upper threshold y_2 and w: 1 -> 0 when it falls to the
lower threshold y_1, becomes a Stewart PSS in y = (x, w, t) with four Voronoi regions in
the (psi, w) plane, psi = (y - y_1)/(y_2 - y_1), indicators g_j = ||(psi, w) - z_j||^2,

    z_1 = (1/4, -1/4):  F_1 = 2 f_A~ - f_down     (below w = 0: pushes w up)
    z_2 = (1/4,  1/4):  F_2 = f_down = (0, -gamma(psi - 1), 0)   (clock frozen)
    z_3 = (3/4,  3/4):  F_3 = f_up   = (0,  gamma(psi), 0)       (clock frozen)
    z_4 = (3/4,  5/4):  F_4 = 2 f_B~ - f_up       (above w = 1: pushes w down)

with f_A~ = (f_A, 0, 1), f_B~ = (f_B, 0, 1) and gamma(z) = a z^2 / (1 + z^2).
Labels checked against the geometry (and nosnoc's `temp_control_model_voronoi.m`): on
w = 0 with psi < 1 the cells 1 and 2 meet, their w-components +gamma(psi - 1) and
-gamma(psi - 1) cancel at theta = (1/2, 1/2) and the sliding mode is exactly f_A~ with
clock rate 1. At psi = 1 the push-down vanishes (gamma(0) = 0), the trajectory crosses
into cell 3 and the push-up gamma(psi) = a/2 lifts w from 0 to 1 in numerical time 2/a
while the clock is frozen; on w = 1 cells 3 and 4 give f_B~. At psi = 0 the push-up
vanishes and cell 2's push-down takes w back to 0. So the push-down lives in cell 2
and vanishes at the upper threshold, the push-up in cell 3 and vanishes at the lower one.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.fesd.system import StewartSystem
from tfcontact.timefreezing.system import TimeFreezingSystem

VORONOI_POINTS = np.array([[0.25, -0.25], [0.25, 0.25], [0.75, 0.75], [0.75, 1.25]])
"""z_1..z_4 in the (psi, w) plane ([HYST22], PROBLEMS.md 0.5)."""


def push_speed(z: ca.SX | float, gain: float) -> ca.SX | float:
    """gamma(z) = a z^2 / (1 + z^2)."""
    return gain * z**2 / (1 + z**2)


def hysteresis_system(
    x: ca.SX,
    u: ca.SX,
    f_a: ca.SX,
    f_b: ca.SX,
    signal: ca.SX,
    thresholds: tuple[float, float],
    *,
    push_gain: float = 1.0,
    state_names: tuple[str, ...] | None = None,
    control_names: tuple[str, ...] | None = None,
) -> TimeFreezingSystem:
    """The time-freezing PSS of a two-mode hysteresis (module docstring).

    Main arguments:
        x: state symbols (without the memory and the clock), shape (n_x, 1).
        u: control symbols, shape (n_u, 1), may be empty.
        f_a: x' in mode A (w = 0), shape (n_x, 1).
        f_b: x' in mode B (w = 1), shape (n_x, 1).
        signal: y(x), the scalar the relay watches.
        thresholds: (y_1, y_2) with y_1 < y_2: w jumps to 1 when y rises to y_2 and back
            to 0 when y falls to y_1.

    Other arguments:
        push_gain: a > 0 in gamma [1/s of numerical time]; a switch takes numerical
            time 2/a.
        state_names, control_names: labels of x and u.

    Returns:
        A `TimeFreezingSystem` of kind "hysteresis" with y = (x, w, t), `memory_index`
        = n_x and `clock_index` = n_x + 1.

    Raises:
        InvalidInput: bad thresholds or gain, or shapes that do not match.
    """
    if not isinstance(x, ca.SX) or x.numel() == 0 or x.shape[1] != 1 or not x.is_valid_input():
        raise InvalidInput("`x` must be a non-empty column of casadi.SX symbols")
    n = x.numel()
    u = ca.SX(0, 1) if u is None else u
    f_a, f_b = ca.SX(f_a), ca.SX(f_b)
    for name, f in (("f_a", f_a), ("f_b", f_b)):
        if f.shape != (n, 1):
            raise InvalidInput(f"`{name}` must have shape ({n}, 1), got {f.shape}")
    signal = ca.SX(signal)
    if signal.numel() != 1:
        raise InvalidInput(f"`signal` must be a scalar, got shape {signal.shape}")
    low, high = (float(v) for v in thresholds)
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise InvalidInput(
            f"`thresholds` must be finite (y_1, y_2) with y_1 < y_2, got {thresholds!r}"
        )
    if not (math.isfinite(push_gain) and push_gain > 0):
        raise InvalidInput(f"`push_gain` must be a finite number > 0, got {push_gain!r}")
    w = ca.SX.sym("w")
    t = ca.SX.sym("t")
    y = ca.vertcat(x, w, t)
    psi = (signal - low) / (high - low)
    zero_x = ca.SX.zeros(n, 1)
    f_a_t = ca.vertcat(f_a, 0, 1)
    f_b_t = ca.vertcat(f_b, 0, 1)
    f_down = ca.vertcat(zero_x, -push_speed(psi - 1, push_gain), 0)
    f_up = ca.vertcat(zero_x, push_speed(psi, push_gain), 0)
    modes = ca.horzcat(2 * f_a_t - f_down, f_down, f_up, 2 * f_b_t - f_up)
    point = ca.vertcat(psi, w)
    indicators = ca.vertcat(*[ca.sumsqr(point - ca.DM(z)) for z in VORONOI_POINTS])
    names = tuple(state_names) if state_names is not None else tuple(f"x{i}" for i in range(n))
    if len(names) != n:
        raise InvalidInput(f"`state_names` has {len(names)} names, expected {n}")
    pss = StewartSystem(
        x=y, u=u, modes=modes, indicators=indicators, switching=ca.vertcat(psi, psi - 1),
        state_names=(*names, "w", "t"), control_names=control_names,
    )
    return TimeFreezingSystem(
        pss=pss, kind="hysteresis", clock_index=n + 1, q_index=slice(0, 0),
        v_index=slice(0, 0), modes=modes, memory_index=n,
        region_names=("mode_a", "push_down", "push_up", "mode_b"),
        info=(("push_gain", float(push_gain)), ("thresholds", (low, high)),
              ("switch_duration", 2.0 / push_gain)),
    )
