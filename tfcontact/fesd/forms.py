"""How each piecewise smooth system form enters a discretisation (DESIGN.md 4.6).

A form supplies, at one stage point, the algebraic variables z, the vector field
x' = f(x, u, z), the algebraic equations (= 0), and two nonnegative vectors of equal
length m, Theta(z) and Lambda(z), with the complementarity 0 <= Theta perp Lambda >= 0.
It also supplies the algebraic variables of an element's end point (a "boundary
point": Lambda only, fixed by cross complementarity) and Lambda at the initial state.

* Stewart:   z = (theta, lambda, mu),  x' = F(x, u) theta,
             g(x) - lambda - mu e = 0,  e^T theta = 1,  Theta = theta, Lambda = lambda.
* Heaviside: z = (alpha, lambda_n, lambda_p),  x' = f(x, u, alpha),
             c(x) - lambda_p + lambda_n = 0,  0 <= alpha <= 1,
             Theta = (alpha, 1 - alpha),  Lambda = (lambda_n, lambda_p);
             with auxiliary variables a (`HeavisideSystem.auxiliary`, e.g. the
             accelerations of the inverse-dynamics form) z also holds a, x' = f(x, u, alpha,
             a), and e(x, u, alpha, a) = 0 joins the algebraic equations. The boundary
             points need no a: only Lambda is asked of them.

References: Stewart, Numer. Math. 58 (1990); Nurkanovic et al., Numer. Math. 2024 (FESD);
Nurkanovic, Pozharskiy, Frey, Diehl, NAHS 2024 (Heaviside step form).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.fesd.system import HeavisideSystem, StewartSystem


@dataclass(frozen=True)
class Block:
    """A named block of algebraic variables at one point: its size and bounds."""

    name: str
    size: int
    lower: float
    upper: float


class Form(ABC):
    """The algebraic part of one stage (or boundary) point of a discretisation."""

    stage_blocks: tuple[Block, ...]
    boundary_blocks: tuple[Block, ...]
    m: int  # length of Theta and Lambda

    @property
    def n_z(self) -> int:
        return sum(b.size for b in self.stage_blocks)

    @property
    def n_zb(self) -> int:
        return sum(b.size for b in self.boundary_blocks)

    def split(self, z: ca.SX, blocks: tuple[Block, ...]) -> dict[str, ca.SX]:
        out, k = {}, 0
        for b in blocks:
            out[b.name] = z[k:k + b.size]
            k += b.size
        return out

    def bounds(self, blocks: tuple[Block, ...]) -> tuple[np.ndarray, np.ndarray]:
        lower = np.concatenate([np.full(b.size, b.lower) for b in blocks])
        upper = np.concatenate([np.full(b.size, b.upper) for b in blocks])
        return lower, upper

    @abstractmethod
    def rhs(self, x: ca.SX, u: ca.SX, z: ca.SX) -> ca.SX:
        """The vector field at a stage point."""

    @abstractmethod
    def algebraic(self, x: ca.SX, u: ca.SX, z: ca.SX) -> ca.SX:
        """Equality constraints (= 0) at a stage point."""

    @abstractmethod
    def theta(self, z: ca.SX) -> ca.SX:
        """Theta(z) >= 0, length m."""

    @abstractmethod
    def lam(self, z: ca.SX) -> ca.SX:
        """Lambda(z) >= 0, length m."""

    @abstractmethod
    def boundary_algebraic(self, x: ca.SX, zb: ca.SX) -> ca.SX:
        """Equality constraints (= 0) at a boundary point."""

    @abstractmethod
    def boundary_lam(self, zb: ca.SX) -> ca.SX:
        """Lambda at a boundary point, length m."""

    @abstractmethod
    def initial_lam(self, x: ca.SX) -> ca.SX:
        """Lambda at a state, in closed form (for the initial state; fmin/fmax of parameters)."""

    @abstractmethod
    def guess(self, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """A consistent stage guess z at a numeric state x (the region of x) and controls u
        (zero if None; only auxiliary variables depend on them)."""


class StewartForm(Form):
    """Stewart's reformulation: theta in argmin g(x)^T theta over the unit simplex."""

    def __init__(self, system: StewartSystem):
        self.system = system
        n_f = system.n_regions
        self.m = n_f
        self.stage_blocks = (
            Block("theta", n_f, 0.0, np.inf),
            Block("lambda", n_f, 0.0, np.inf),
            Block("mu", 1, -np.inf, np.inf),
        )
        self.boundary_blocks = (
            Block("lambda_end", n_f, 0.0, np.inf),
            Block("mu_end", 1, -np.inf, np.inf),
        )
        self._F = ca.Function("modes", [system.x, system.u], [system.modes])
        self._g = ca.Function("indicators", [system.x], [system.indicators])

    def rhs(self, x, u, z):
        return ca.mtimes(self._F(x, u), self.split(z, self.stage_blocks)["theta"])

    def algebraic(self, x, u, z):
        v = self.split(z, self.stage_blocks)
        return ca.vertcat(self._g(x) - v["lambda"] - v["mu"], ca.sum1(v["theta"]) - 1)

    def theta(self, z):
        return self.split(z, self.stage_blocks)["theta"]

    def lam(self, z):
        return self.split(z, self.stage_blocks)["lambda"]

    def boundary_algebraic(self, x, zb):
        v = self.split(zb, self.boundary_blocks)
        return self._g(x) - v["lambda_end"] - v["mu_end"]

    def boundary_lam(self, zb):
        return self.split(zb, self.boundary_blocks)["lambda_end"]

    def initial_lam(self, x):
        g = self._g(x)
        return g - ca.mmin(g)

    def guess(self, x, u=None):
        g = np.asarray(self._g(x)).reshape(-1)
        theta = np.zeros(self.m)
        theta[np.argmin(g)] = 1.0
        return np.concatenate([theta, g - g.min(), [g.min()]])


class HeavisideForm(Form):
    """The Heaviside step form: alpha_j in H(c_j(x)), c = lambda_p - lambda_n."""

    def __init__(self, system: HeavisideSystem):
        self.system = system
        n_c = system.n_switching
        self.m = 2 * n_c
        n_a = system.n_auxiliary
        self.stage_blocks = (
            Block("alpha", n_c, 0.0, 1.0),
            Block("lambda_n", n_c, 0.0, np.inf),
            Block("lambda_p", n_c, 0.0, np.inf),
        ) + ((Block("auxiliary", n_a, -np.inf, np.inf),) if n_a else ())
        self.boundary_blocks = (
            Block("lambda_n_end", n_c, 0.0, np.inf),
            Block("lambda_p_end", n_c, 0.0, np.inf),
        )
        inputs = [system.x, system.u, system.alpha, system.auxiliary]
        self._f = ca.Function("rhs", inputs, [system.rhs])
        self._e = ca.Function("auxiliary_equations", inputs, [system.auxiliary_equations])
        self._c = ca.Function("switching", [system.x], [system.switching])
        # a from e(x, u, alpha, a) = 0 by one Newton step from a = 0 (exact for e affine in
        # a, as M(q) a - forces is): the stage guess
        e = system.auxiliary_equations
        step = -ca.solve(ca.jacobian(e, system.auxiliary), ca.substitute(
            e, system.auxiliary, ca.SX.zeros(n_a))) if n_a else ca.SX(0, 1)
        self._a_guess = ca.Function("auxiliary_guess", inputs[:3], [step])

    def _auxiliary(self, z):
        if not self.system.n_auxiliary:
            return ca.SX(0, 1)
        return self.split(z, self.stage_blocks)["auxiliary"]

    def rhs(self, x, u, z):
        return self._f(x, u, self.split(z, self.stage_blocks)["alpha"], self._auxiliary(z))

    def algebraic(self, x, u, z):
        v = self.split(z, self.stage_blocks)
        return ca.vertcat(self._c(x) - v["lambda_p"] + v["lambda_n"],
                          self._e(x, u, v["alpha"], self._auxiliary(z)))

    def theta(self, z):
        alpha = self.split(z, self.stage_blocks)["alpha"]
        return ca.vertcat(alpha, 1 - alpha)

    def lam(self, z):
        v = self.split(z, self.stage_blocks)
        return ca.vertcat(v["lambda_n"], v["lambda_p"])

    def boundary_algebraic(self, x, zb):
        v = self.split(zb, self.boundary_blocks)
        return self._c(x) - v["lambda_p_end"] + v["lambda_n_end"]

    def boundary_lam(self, zb):
        v = self.split(zb, self.boundary_blocks)
        return ca.vertcat(v["lambda_n_end"], v["lambda_p_end"])

    def initial_lam(self, x):
        c = self._c(x)
        return ca.vertcat(ca.fmax(-c, 0), ca.fmax(c, 0))

    def guess(self, x, u=None):
        c = np.asarray(self._c(x)).reshape(-1)
        alpha = np.where(c > 0, 1.0, np.where(c < 0, 0.0, 0.5))
        parts = [alpha, np.maximum(-c, 0), np.maximum(c, 0)]
        if self.system.n_auxiliary:
            u = np.zeros(self.system.n_u) if u is None else np.asarray(u, dtype=float)
            parts.append(np.asarray(self._a_guess(x, u.reshape(-1), alpha)).reshape(-1))
        return np.concatenate(parts)


def form_of(system: object) -> Form:
    """The form of a StewartSystem or HeavisideSystem; anything else raises InvalidInput."""
    if isinstance(system, StewartSystem):
        return StewartForm(system)
    if isinstance(system, HeavisideSystem):
        return HeavisideForm(system)
    raise InvalidInput(
        f"`system` must be a StewartSystem or HeavisideSystem, got {type(system).__name__}"
    )
