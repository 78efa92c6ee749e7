"""The statement of an optimal control problem of a piecewise smooth system.

    min_{x(.), u(.)}  int_0^T L(x, u) dt + M(x(T))
    s.t.   x' in F(x, u) (a StewartSystem or HeavisideSystem),   x(0) = x0,
           u_lower <= u <= u_upper   (u piecewise constant on N intervals),
           x_lower <= x <= x_upper   (at every grid point),
           path_lower <= p(x, u) <= path_upper,
           terminal_lower <= r(x(T)) <= terminal_upper,
           b_k(x(t_k)) within its bounds at the interval boundaries t_k = k T / N.

Nothing here knows about robots or time-freezing: the time-freezing layer supplies the
system, the clock constraints through `boundary_constraints`, and the speed of time as a
control.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.fesd.system import HeavisideSystem, StewartSystem
from tfcontact.symbolic import check_depends


def _bound_vector(value: object, n: int, default: float, name: str) -> np.ndarray:
    if value is None:
        return np.full(n, default)
    arr = np.asarray(value, dtype=float)
    if arr.size == 1 and n != 1:
        return np.full(n, float(arr.reshape(-1)[0]))
    if arr.size != n:
        raise InvalidInput(f"`{name}` has {arr.size} entries, expected {n}")
    return arr.reshape(-1).copy()


@dataclass(frozen=True, eq=False)
class Constraint:
    """lower <= expression <= upper (equality where lower = upper).

    Args:
        expression: SX column (n, 1).
        lower, upper: bounds, arrays (n,) or scalars. Neither given: the equality
            expression = 0; only one given: the other side is unbounded.
    """

    expression: ca.SX
    lower: np.ndarray | float | None = None
    upper: np.ndarray | float | None = None

    def __post_init__(self) -> None:
        expr = self.expression
        if isinstance(expr, float | int | np.ndarray | ca.DM):
            expr = ca.SX(ca.DM(expr))
        if not isinstance(expr, ca.SX):
            raise InvalidInput(
                f"`expression` must be a casadi.SX expression, got {type(expr).__name__}"
            )
        if expr.numel() and expr.shape[1] != 1:
            expr = ca.vec(expr)
        n = expr.numel()
        if self.lower is None and self.upper is None:
            lower, upper = np.zeros(n), np.zeros(n)
        else:
            lower = _bound_vector(self.lower, n, -np.inf, "lower")
            upper = _bound_vector(self.upper, n, np.inf, "upper")
        if np.any(lower > upper):
            i = int(np.argmax(lower > upper))
            raise InvalidInput(f"`lower[{i}]` = {lower[i]} exceeds `upper[{i}]` = {upper[i]}")
        object.__setattr__(self, "expression", expr)
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @property
    def size(self) -> int:
        return self.expression.numel()

    def rows(self, indices: Sequence[int]) -> Constraint | None:
        """These rows only, in the order given (None when `indices` is empty)."""
        indices = list(indices)
        if any(not 0 <= i < self.size for i in indices):
            raise InvalidInput(f"row indices {indices} outside the constraint's {self.size} "
                               "rows")
        if not indices:
            return None
        return Constraint(self.expression[indices], self.lower[indices], self.upper[indices])


BoundaryHook = Callable[[int, ca.SX], Constraint | None]
"""(k, x_k) -> Constraint on the state x_k at the interval boundary t_k = k T / N, or None."""


@dataclass(frozen=True, eq=False)
class OptimalControlProblem:
    """An OCP of a piecewise smooth system with piecewise constant controls.

    Main args:
        system: `StewartSystem` or `HeavisideSystem`.
        x0: initial state, shape (n_x,).
        horizon: T [s] (numerical time for time-freezing systems).
        n_intervals: N control intervals.

    Other args:
        lagrange: L(x, u), SX scalar in system.x and system.u, integrated over [0, T]
            with the collocation quadrature [cost]/[s].
        mayer: M(x(T)), SX scalar in system.x [cost].
        u_lower, u_upper: control bounds, (n_u,) or scalar.
        x_lower, x_upper: state bounds at every grid point after x0, (n_x,) or scalar.
        path: `Constraint` in x and u, imposed at every stage and element end point.
        terminal: `Constraint` in x, imposed at x(T).
        boundary_constraints: hook (k, x_k) -> Constraint | None, called in order for
            k = 1..N with the SX state at the interval boundary t_k = k T / N (a hook
            may keep earlier boundaries: `ContactProblem.periodicity` does)
            (time-freezing: clock t_k = k T_phys / N).
        x_guess: initial guess of the state: (n_x,) (constant) or (N + 1, n_x)
            (at the interval boundaries, interpolated linearly); default x0.
        u_guess: initial guess of the controls: (n_u,) or (N, n_u); default 0 clipped
            into the bounds.
    """

    system: StewartSystem | HeavisideSystem
    x0: np.ndarray
    horizon: float
    n_intervals: int
    lagrange: ca.SX = field(default_factory=lambda: ca.SX(0))
    mayer: ca.SX = field(default_factory=lambda: ca.SX(0))
    u_lower: np.ndarray | float | None = None
    u_upper: np.ndarray | float | None = None
    x_lower: np.ndarray | float | None = None
    x_upper: np.ndarray | float | None = None
    path: Constraint | None = None
    terminal: Constraint | None = None
    boundary_constraints: BoundaryHook | None = None
    x_guess: np.ndarray | None = None
    u_guess: np.ndarray | None = None

    def __post_init__(self) -> None:
        sys = self.system
        if not isinstance(sys, StewartSystem | HeavisideSystem):
            raise InvalidInput(
                f"`system` must be a StewartSystem or HeavisideSystem, got {type(sys).__name__}"
            )
        n_x, n_u = sys.n_x, sys.n_u
        x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        if x0.size != n_x:
            raise InvalidInput(f"`x0` has {x0.size} entries, expected n_x = {n_x}")
        if not np.all(np.isfinite(x0)):
            raise InvalidInput(f"`x0` must be finite, got {x0}")
        object.__setattr__(self, "x0", x0)
        if not (np.isfinite(self.horizon) and self.horizon > 0):
            raise InvalidInput(f"`horizon` must be a positive number [s], got {self.horizon!r}")
        n = positive_int(self.n_intervals, "n_intervals")
        for name in ("lagrange", "mayer"):
            expr = getattr(self, name)
            if isinstance(expr, float | int):
                expr = ca.SX(expr)
            if not isinstance(expr, ca.SX) or expr.numel() != 1:
                raise InvalidInput(f"`{name}` must be a scalar casadi.SX expression")
            object.__setattr__(self, name, expr)
        check_depends(self.lagrange, [sys.x, sys.u], "lagrange", "the states and controls")
        check_depends(self.mayer, [sys.x], "mayer", "the states")
        object.__setattr__(self, "u_lower", _bound_vector(self.u_lower, n_u, -np.inf, "u_lower"))
        object.__setattr__(self, "u_upper", _bound_vector(self.u_upper, n_u, np.inf, "u_upper"))
        object.__setattr__(self, "x_lower", _bound_vector(self.x_lower, n_x, -np.inf, "x_lower"))
        object.__setattr__(self, "x_upper", _bound_vector(self.x_upper, n_x, np.inf, "x_upper"))
        for lo, hi in (("u_lower", "u_upper"), ("x_lower", "x_upper")):
            a, b = getattr(self, lo), getattr(self, hi)
            if np.any(a > b):
                i = int(np.argmax(a > b))
                raise InvalidInput(f"`{lo}[{i}]` = {a[i]} exceeds `{hi}[{i}]` = {b[i]}")
        for name, allowed, what in (("path", [sys.x, sys.u], "the states and controls"),
                                    ("terminal", [sys.x], "the states")):
            con = getattr(self, name)
            if con is not None:
                if not isinstance(con, Constraint):
                    raise InvalidInput(f"`{name}` must be a Constraint(expression, lower, upper)")
                check_depends(con.expression, allowed, name, what)
        if self.boundary_constraints is not None and not callable(self.boundary_constraints):
            raise InvalidInput("`boundary_constraints` must be a callable (k, x_k) -> Constraint")
        if self.x_guess is not None:
            xg = np.asarray(self.x_guess, dtype=float)
            if xg.shape not in ((n_x,), (n + 1, n_x)):
                raise InvalidInput(
                    f"`x_guess` must have shape ({n_x},) or (N + 1, n_x) = ({n + 1}, {n_x}), "
                    f"got {xg.shape}"
                )
            object.__setattr__(self, "x_guess", xg)
        if self.u_guess is not None:
            ug = np.asarray(self.u_guess, dtype=float)
            if ug.size == n_u:
                ug = ug.reshape(n_u)
            elif n_u == 1 and ug.shape == (n,):
                ug = ug.reshape(n, 1)
            if ug.shape not in ((n_u,), (n, n_u)):
                raise InvalidInput(
                    f"`u_guess` must have shape ({n_u},) or (N, n_u) = ({n}, {n_u}), "
                    f"got {ug.shape}"
                )
            object.__setattr__(self, "u_guess", ug)

    @property
    def n_x(self) -> int:
        return self.system.n_x

    @property
    def n_u(self) -> int:
        return self.system.n_u
