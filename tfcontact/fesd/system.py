"""Piecewise smooth systems: the input of the FESD layer.

Two representations of the same idea, a vector field that switches when
switching functions c(x) change sign (DESIGN.md section 4.6):

* `StewartSystem`: x' = F(x, u) theta, theta in argmin_theta g(x)^T theta over the
  unit simplex; region i is where the indicator g_i(x) is smallest. With a sign
  matrix S (regions as sign patterns of c) g = -S c.
* `HeavisideSystem`: x' = f(x, u, alpha), alpha_j in H(c_j(x)) (the set-valued
  Heaviside step), f multi-affine in alpha. Regions that are unions and
  intersections of sign conditions (time-freezing) are products of alpha and 1 - alpha.
  Optionally f also depends on auxiliary variables a fixed by equations
  e(x, u, alpha, a) = 0 (the inverse-dynamics form of time-freezing: a the accelerations,
  e = M(q) a - forces, so that no expression holds M^-1); a discretisation carries a
  and e at every stage point.

Both are immutable descriptions built from CasADi SX symbols; nothing is
discretised or solved here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.symbolic import as_sx, check_depends, labels


def _column(expr: ca.SX, name: str) -> ca.SX:
    expr = as_sx(expr, name)
    if expr.numel() == 0:
        return ca.SX(0, 1)
    if expr.shape[1] != 1:
        raise InvalidInput(f"`{name}` must be a column vector, got shape {expr.shape}")
    return expr


def _symbols(expr: ca.SX, name: str) -> ca.SX:
    expr = _column(expr, name)
    if expr.numel() and not expr.is_valid_input():
        raise InvalidInput(f"`{name}` must be a vector of pure symbols (casadi.SX.sym)")
    return expr


@dataclass(frozen=True, eq=False)
class StewartSystem:
    """x' = F(x, u) theta with theta in argmin g(x)^T theta over the unit simplex.

    Args:
        x: state symbols, shape (n_x, 1).
        u: control symbols, shape (n_u, 1) (may be empty).
        modes: F(x, u), shape (n_x, n_f): column i is the vector field of region i.
        indicators: g(x), shape (n_f, 1): region i is where g_i is the smallest.
        switching: the switching functions c(x) the indicators are built from
            (for diagnostics and switch-time reporting), shape (n_c, 1).
        state_names, control_names: labels for plots and files.
    """

    x: ca.SX
    u: ca.SX
    modes: ca.SX
    indicators: ca.SX
    switching: ca.SX = field(default_factory=lambda: ca.SX(0, 1))
    state_names: tuple[str, ...] | None = None
    control_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        x = _symbols(self.x, "x")
        u = _symbols(self.u, "u")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "modes", as_sx(self.modes, "modes"))
        if self.modes.shape[0] != x.numel():
            raise InvalidInput(
                f"`modes` must have one row per state: got shape {self.modes.shape}, "
                f"n_x = {x.numel()}"
            )
        g = _column(self.indicators, "indicators")
        if g.numel() != self.modes.shape[1]:
            raise InvalidInput(
                f"`indicators` has {g.numel()} entries but `modes` has "
                f"{self.modes.shape[1]} columns; "
                "give one indicator per region"
            )
        if g.numel() < 2:
            raise InvalidInput("a piecewise smooth system needs at least 2 regions")
        object.__setattr__(self, "indicators", g)
        object.__setattr__(self, "switching", _column(self.switching, "switching"))
        check_depends(self.indicators, [x], "indicators", "the states")
        check_depends(self.switching, [x], "switching", "the states")
        check_depends(self.modes, [x, u], "modes", "the states and controls")
        object.__setattr__(
            self, "state_names", labels(self.state_names, x.numel(), "x", "state_names")
        )
        object.__setattr__(
            self, "control_names", labels(self.control_names, u.numel(), "u", "control_names")
        )

    @classmethod
    def from_sign_matrix(
        cls,
        x: ca.SX,
        u: ca.SX,
        modes: ca.SX,
        switching: ca.SX,
        signs: np.ndarray,
        **names: tuple[str, ...],
    ) -> StewartSystem:
        """Regions as sign patterns of c: region i is {x : sign(c(x)) = signs[i]}.

        Args:
            signs: the sign matrix S, shape (n_f, n_c), entries +1 or -1.
        """
        switching = _column(switching, "switching")
        modes = as_sx(modes, "modes")
        signs = np.asarray(signs, dtype=float)
        if signs.ndim != 2 or signs.shape != (modes.shape[1], switching.numel()):
            raise InvalidInput(
                f"`signs` must have shape (n_f, n_c) = ({modes.shape[1]}, {switching.numel()}), "
                f"got {signs.shape}"
            )
        if not np.all(np.isin(signs, (-1.0, 1.0))):
            raise InvalidInput("`signs` entries must be +1 or -1")
        if len({tuple(r) for r in signs}) != signs.shape[0]:
            raise InvalidInput("`signs` has two equal rows: each region needs its own sign pattern")
        indicators = -ca.mtimes(ca.DM(signs), switching)
        return cls(x=x, u=u, modes=modes, indicators=indicators, switching=switching, **names)

    @property
    def n_x(self) -> int:
        return self.x.numel()

    @property
    def n_u(self) -> int:
        return self.u.numel()

    @property
    def n_regions(self) -> int:
        return self.modes.shape[1]

    def with_dynamics(self, rows: Callable[[ca.SX], ca.SX], *, x: ca.SX | None = None,
                      u: ca.SX | None = None, state_names: tuple[str, ...] | None = None,
                      control_names: tuple[str, ...] | None = None) -> StewartSystem:
        """The same regions with every mode's rows passed through `rows` (applied to the
        matrix F whose columns are the modes), optionally with new state and control
        symbols and names (default: these)."""
        return StewartSystem(
            x=self.x if x is None else x, u=self.u if u is None else u,
            modes=rows(self.modes), indicators=self.indicators, switching=self.switching,
            state_names=self.state_names if state_names is None else state_names,
            control_names=self.control_names if control_names is None else control_names)

    def theta(self, algebraic: Mapping[str, np.ndarray]) -> np.ndarray:
        """The convex multipliers Theta of the regions from a discretisation's algebraic
        variables (`Discretization.algebraic`), shape (..., n_regions)."""
        return algebraic["theta"]


@dataclass(frozen=True, eq=False)
class HeavisideSystem:
    """x' = f(x, u, alpha) with alpha_j in H(c_j(x)), the set-valued Heaviside step.

    H(c) = {1} for c > 0, {0} for c < 0 and [0, 1] for c = 0.

    Args:
        x: state symbols, shape (n_x, 1).
        u: control symbols, shape (n_u, 1) (may be empty).
        alpha: step symbols, one per switching function, shape (n_c, 1).
        rhs: f(x, u, alpha, a), shape (n_x, 1), multi-affine in alpha.
        switching: c(x), shape (n_c, 1).
        state_names, control_names: labels for plots and files.
        auxiliary: a, symbols of auxiliary variables, shape (n_a, 1); empty (default)
            for an explicit f(x, u, alpha).
        auxiliary_equations: e(x, u, alpha, a) = 0, shape (n_a, 1), which must fix a
            (de/da nonsingular; affine in a for `HeavisideForm.guess` to be exact).
    """

    x: ca.SX
    u: ca.SX
    alpha: ca.SX
    rhs: ca.SX
    switching: ca.SX
    state_names: tuple[str, ...] | None = None
    control_names: tuple[str, ...] | None = None
    auxiliary: ca.SX | None = None
    auxiliary_equations: ca.SX | None = None

    def __post_init__(self) -> None:
        x = _symbols(self.x, "x")
        u = _symbols(self.u, "u")
        alpha = _symbols(self.alpha, "alpha")
        c = _column(self.switching, "switching")
        rhs = _column(self.rhs, "rhs")
        if rhs.numel() != x.numel():
            raise InvalidInput(f"`rhs` has {rhs.numel()} entries, expected n_x = {x.numel()}")
        if c.numel() == 0:
            raise InvalidInput("`switching` is empty: a Heaviside system needs switching functions")
        if alpha.numel() != c.numel():
            raise InvalidInput(
                f"`alpha` has {alpha.numel()} entries but `switching` has {c.numel()}; "
                "give one step variable per switching function"
            )
        aux = _symbols(ca.SX(0, 1) if self.auxiliary is None else self.auxiliary, "auxiliary")
        equations = _column(ca.SX(0, 1) if self.auxiliary_equations is None
                            else self.auxiliary_equations, "auxiliary_equations")
        if equations.numel() != aux.numel():
            raise InvalidInput(
                f"`auxiliary_equations` has {equations.numel()} entries but `auxiliary` has "
                f"{aux.numel()}: give one equation per auxiliary variable")
        check_depends(c, [x], "switching", "the states")
        check_depends(rhs, [x, u, alpha, aux], "rhs",
                      "the states, controls, alpha and the auxiliary variables")
        check_depends(equations, [x, u, alpha, aux], "auxiliary_equations",
                      "the states, controls, alpha and the auxiliary variables")
        for name, value in (("x", x), ("u", u), ("alpha", alpha), ("rhs", rhs), ("switching", c),
                            ("auxiliary", aux), ("auxiliary_equations", equations)):
            object.__setattr__(self, name, value)
        object.__setattr__(
            self, "state_names", labels(self.state_names, x.numel(), "x", "state_names")
        )
        object.__setattr__(
            self, "control_names", labels(self.control_names, u.numel(), "u", "control_names")
        )

    @property
    def n_x(self) -> int:
        return self.x.numel()

    @property
    def n_u(self) -> int:
        return self.u.numel()

    @property
    def n_switching(self) -> int:
        return self.switching.numel()

    @property
    def n_auxiliary(self) -> int:
        return self.auxiliary.numel()

    def with_dynamics(self, rows: Callable[[ca.SX], ca.SX], *, x: ca.SX | None = None,
                      u: ca.SX | None = None, state_names: tuple[str, ...] | None = None,
                      control_names: tuple[str, ...] | None = None) -> HeavisideSystem:
        """The same switching with the right-hand side's rows passed through `rows`
        (f is multi-affine in alpha, so a row map that is linear in the modes may act on f
        directly), optionally with new state and control symbols and names. The auxiliary
        variables and their equations are kept: they define f's terms, not its rows."""
        return HeavisideSystem(
            x=self.x if x is None else x, u=self.u if u is None else u, alpha=self.alpha,
            rhs=rows(self.rhs), switching=self.switching,
            state_names=self.state_names if state_names is None else state_names,
            control_names=self.control_names if control_names is None else control_names,
            auxiliary=self.auxiliary, auxiliary_equations=self.auxiliary_equations)

    def theta(self, algebraic: Mapping[str, np.ndarray]) -> np.ndarray:
        """The Heaviside steps as multipliers, (alpha, 1 - alpha), from a discretisation's
        algebraic variables, shape (..., 2 n_switching)."""
        alpha = algebraic["alpha"]
        return np.concatenate([alpha, 1 - alpha], axis=-1)


PiecewiseSmoothSystem = StewartSystem | HeavisideSystem
