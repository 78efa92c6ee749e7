"""The time-freezing system: a piecewise smooth system plus the metadata to read it.

The builder (`time_freeze`, `hysteresis_system`) returns a `TimeFreezingSystem`:
the piecewise smooth system `pss` (a `StewartSystem` or `HeavisideSystem` of the
FESD layer) in the state y = (q, v, t) (or (x, w, t) for hysteresis) and the indices
that say which state is what. Two transformations used by the OCP layer:

* `with_speed_of_time`: append a control s (speed of time, DESIGN.md 4.1,
  [AUTO23] eq. (35)) that multiplies every mode: y' = s F(y, u) theta.
* `with_lagrange_cost`: append a quadrature state l' = L(x, u) dt/dtau, so that a
  Lagrange cost int L dt in *physical* time is l(T_numerical); frozen pieces add
  nothing ([AUTO23] eq. (29)), and with a speed of time the rate is s L.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.fesd.system import HeavisideSystem, StewartSystem

PiecewiseSmoothSystem = StewartSystem | HeavisideSystem


@dataclass(frozen=True, eq=False)
class TimeFreezingSystem:
    """A time-freezing piecewise smooth system and its metadata.

    Attributes:
        pss: the piecewise smooth system in numerical time tau; its state y = pss.x.
        kind: "inelastic", "elastic" or "hysteresis".
        clock_index: index of the clock t in y (dt/dtau = 0 while frozen).
        q_index, v_index: slices of q and v in y (empty for hysteresis).
        memory_index: index of the hysteresis memory w in y (None otherwise).
        cost_index: index of the Lagrange-cost quadrature state (None if absent).
        speed_of_time_index: index of the speed of time s in pss.u (None if absent).
        cls: the complementarity Lagrangian system it was built from (None for hysteresis).
        modes: the mode vector fields as columns, shape (n_y, n_f) (for the Heaviside form
            the same fields that `weights` combine).
        weights: Heaviside form only: theta(alpha), shape (n_f, 1), so that
            pss.rhs == modes @ weights (with `InverseDynamics` where the acceleration
            variables solve their equations M(q) a = sum theta_k F_k); None for the
            Stewart form.
        region_names: one label per mode.
        info: method parameters (a_n, stiffness, damping, push gain, ...).
    """

    pss: PiecewiseSmoothSystem
    kind: str
    clock_index: int
    q_index: slice
    v_index: slice
    modes: ca.SX
    region_names: tuple[str, ...]
    weights: ca.SX | None = None
    memory_index: int | None = None
    cost_index: int | None = None
    speed_of_time_index: int | None = None
    cls: Any = None
    info: tuple[tuple[str, Any], ...] = ()

    @property
    def y(self) -> ca.SX:
        """The state symbols y (the PSS's x)."""
        return self.pss.x

    @property
    def u(self) -> ca.SX:
        return self.pss.u

    @property
    def n_y(self) -> int:
        return self.pss.n_x

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.pss.state_names

    def parameter(self, name: str) -> Any:
        """A method parameter recorded in `info` (e.g. "stiffness", "damping")."""
        for key, value in self.info:
            if key == name:
                return value
        raise InvalidInput(f"`{name}` is not a parameter of this system: {dict(self.info)}")

    def initial_state(self, *values: Any, t0: float = 0.0) -> np.ndarray:
        """y0 from the physical initial state.

        For a CLS: `initial_state(q0, v0)` gives (q0, v0, t0) (and cost 0 if present).
        For hysteresis: `initial_state(x0, w0)` gives (x0, w0, t0).
        """
        y0 = np.zeros(self.n_y)
        if self.kind == "hysteresis":
            x0, w0 = values
            y0[: self.memory_index] = np.atleast_1d(np.asarray(x0, dtype=float))
            y0[self.memory_index] = float(w0)
        else:
            q0, v0 = values
            q0 = np.atleast_1d(np.asarray(q0, dtype=float))
            v0 = np.atleast_1d(np.asarray(v0, dtype=float))
            n = self.q_index.stop - self.q_index.start
            if q0.shape != (n,) or v0.shape != (n,):
                raise InvalidInput(
                    f"`q0` and `v0` must have shape ({n},), got {q0.shape} and {v0.shape}"
                )
            y0[self.q_index] = q0
            y0[self.v_index] = v0
        y0[self.clock_index] = t0
        return y0

    def function(self) -> ca.Function:
        """The modes as a CasADi function F(y, u) -> (n_y, n_f) (for tests and plots)."""
        return ca.Function("modes", [self.pss.x, self.pss.u], [self.modes])


def with_speed_of_time(system: TimeFreezingSystem, *, name: str = "s") -> TimeFreezingSystem:
    """The same PSS with a control s appended that multiplies every mode.

    y' = s F(y, u) theta (Stewart) or y' = s f(y, u, alpha) (Heaviside), so the clock runs
    at dt/dtau = s where it is not frozen. The OCP bounds 1 <= s <= s_max per control
    interval and imposes t(T_numerical) = T_physical (DESIGN.md 4.1, PROBLEMS.md 0.4).
    Apply it before or after `with_lagrange_cost`: the cost rate is L dt/dtau either way.

    Args:
        system: a time-freezing system without a speed of time yet.
        name: the control's name.

    Returns:
        A new `TimeFreezingSystem` whose pss.u = (u, s); `speed_of_time_index` = n_u.
    """
    if system.speed_of_time_index is not None:
        raise IncompatibleOptions("`system` already has a speed of time control")
    s = ca.SX.sym(name)
    pss = system.pss
    u = ca.vertcat(pss.u, s)
    modes = system.modes * s
    new = pss.with_dynamics(lambda rows: rows * s, u=u,
                            control_names=(*pss.control_names, name))
    return replace(system, pss=new, modes=modes, speed_of_time_index=pss.n_u)


def with_lagrange_cost(
    system: TimeFreezingSystem, running_cost: ca.SX, *, name: str = "cost"
) -> TimeFreezingSystem:
    """Append a quadrature state l with l' = L(y, u) dt/dtau (physical-time cost).

    The rate is the running cost times the clock row of each mode: L in free flight,
    gamma L on a persistent-contact sliding mode, 0 while frozen ([AUTO23] eq. (29)), and
    s L with a speed of time. Then l(T_numerical) = int_0^T L dt in physical time.
    The new state is inserted just before the clock (as nosnoc does).

    Args:
        system: the time-freezing system.
        running_cost: L, a scalar SX expression of the states y and controls pss.u
            [cost units per second].
        name: the state's name.

    Returns:
        A new `TimeFreezingSystem` with `cost_index` set and the clock index shifted by one.
    """
    if system.cost_index is not None:
        raise IncompatibleOptions("`system` already has a cost state")
    running_cost = ca.SX(running_cost) if not isinstance(running_cost, ca.SX) else running_cost
    if running_cost.numel() != 1:
        raise InvalidInput(f"`running_cost` must be a scalar, got shape {running_cost.shape}")
    pss = system.pss
    allowed = {s.name() for s in ca.symvar(ca.vertcat(pss.x, pss.u))}
    extra = sorted({s.name() for s in ca.symvar(running_cost)} - allowed)
    if extra:
        raise InvalidInput(f"`running_cost` depends on symbols {extra} that are not in y or u")
    k = system.clock_index
    ell = ca.SX.sym(name)
    x = ca.vertcat(pss.x[:k], ell, pss.x[k:])
    state_names = (*pss.state_names[:k], name, *pss.state_names[k:])

    def insert(rows: ca.SX) -> ca.SX:
        rate = running_cost * rows[k, :]
        return ca.vertcat(rows[:k, :], rate, rows[k:, :])

    modes = insert(system.modes)
    new = pss.with_dynamics(insert, x=x, state_names=state_names)

    def shift(index: slice) -> slice:
        if index.start is not None and index.start >= k:
            return slice(index.start + 1, index.stop + 1)
        return index

    memory = system.memory_index
    return replace(
        system, pss=new, modes=modes, clock_index=k + 1, cost_index=k,
        q_index=shift(system.q_index), v_index=shift(system.v_index),
        memory_index=memory if memory is None or memory < k else memory + 1,
    )
