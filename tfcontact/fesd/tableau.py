"""Butcher tableaus of collocation methods, computed from their collocation points.

A collocation method with points 0 < c_1 < ... < c_s <= 1 on the unit interval has

    A_ij = int_0^{c_i} l_j(t) dt,    b_j = int_0^1 l_j(t) dt,

where l_j is the Lagrange polynomial of degree s - 1 with l_j(c_k) = delta_jk
(Hairer, Wanner, "Solving ODEs II", section IV.5). The points are

* Radau IIA: the zeros of P_s(2c - 1) - P_{s-1}(2c - 1) (c_s = 1), order 2s - 1;
* Gauss-Legendre: the zeros of P_s(2c - 1), order 2s;

with P_k the Legendre polynomials. Nothing is typed in: the coefficients are
computed here and checked by `Tableau.__post_init__`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.polynomial import legendre

from tfcontact.errors import InvalidInput, positive_int

_CHECK_TOL = 1e-12
_MAX_STAGES = 9


@dataclass(frozen=True, eq=False)
class Tableau:
    """The Butcher tableau (A, b, c) of an s-stage Runge-Kutta method.

    Args:
        A: stage coefficients, shape (s, s).
        b: weights, shape (s,), sum(b) = 1.
        c: nodes, shape (s,), c_i = sum_j A_ij.
        order: the classical order of the method on smooth problems.
        name: a label such as "Radau IIA (s=2)".
    """

    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int
    name: str

    def __post_init__(self) -> None:
        A = np.array(self.A, dtype=float)
        b = np.array(self.b, dtype=float).reshape(-1)
        c = np.array(self.c, dtype=float).reshape(-1)
        s = b.size
        if s < 1:
            raise InvalidInput("`b` is empty: a tableau needs at least one stage")
        if A.shape != (s, s) or c.size != s:
            raise InvalidInput(
                f"`A` must have shape (s, s) and `c` shape (s,) with s = len(b) = {s}, "
                f"got A {A.shape} and c ({c.size},)"
            )
        if abs(b.sum() - 1.0) > _CHECK_TOL:
            raise InvalidInput(f"the weights `b` must sum to 1, got sum(b) = {b.sum()!r}")
        rows = A.sum(axis=1)
        if np.max(np.abs(rows - c)) > _CHECK_TOL:
            raise InvalidInput(
                f"the row sums of `A` must equal `c`: got {rows.tolist()} and {c.tolist()}"
            )
        positive_int(self.order, "order")
        for name, value in (("A", A), ("b", b), ("c", c)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def stages(self) -> int:
        """The number of stages s."""
        return self.b.size

    @property
    def stiffly_accurate(self) -> bool:
        """True when the last stage is the end point (c_s = 1 and b = A[s-1]), as for Radau IIA.

        Then the state and the algebraic variables at an element's end are those of its
        last stage, and the FESD discretisation needs no separate boundary point.
        """
        return bool(abs(self.c[-1] - 1.0) <= _CHECK_TOL and
                    np.max(np.abs(self.A[-1] - self.b)) <= _CHECK_TOL)


def collocation_tableau(points: np.ndarray, order: int, name: str) -> Tableau:
    """The tableau of the collocation method with the given points in (0, 1].

    Args:
        points: collocation points c, shape (s,), distinct, in (0, 1].
        order: the method's order (stated by the caller, from the theory of its points).
        name: a label.
    """
    c = np.sort(np.asarray(points, dtype=float).reshape(-1))
    s = c.size
    if s < 1 or np.any(c <= 0) or np.any(c > 1) or np.any(np.diff(c) <= 0):
        raise InvalidInput(f"`points` must be distinct and lie in (0, 1], got {c.tolist()}")
    # Lagrange basis in the monomial basis: l_j(t) = sum_k coef[k, j] t^k with V coef = I,
    # V[i, k] = c_i^k. Integrals of t^k from 0 to x are x^(k+1) / (k+1).
    powers = np.arange(s)
    vandermonde = c[:, None] ** powers[None, :]
    coef = np.linalg.solve(vandermonde, np.eye(s))
    integrals = c[:, None] ** (powers[None, :] + 1) / (powers[None, :] + 1)
    A = integrals @ coef
    b = (1.0 / (powers + 1)) @ coef
    # Remove the round-off of the solve so that the consistency checks hold to 1e-15.
    A = A + ((c - A.sum(axis=1)) / s)[:, None]
    b = b / b.sum()
    return Tableau(A=A, b=b, c=c, order=order, name=name)


def lagrange_weights(nodes: np.ndarray, theta: float) -> np.ndarray:
    """The Lagrange basis through `nodes` at `theta`: weights w with w @ values the
    interpolation polynomial's value there (a collocation element's state from its start
    and stage values at nodes (0, c_1, ..., c_s))."""
    nodes = np.asarray(nodes, dtype=float)
    weights = np.ones(nodes.size)
    for j, nj in enumerate(nodes):
        for k, nk in enumerate(nodes):
            if k != j:
                weights[j] *= (theta - nk) / (nj - nk)
    return weights


def _refine(roots: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """Two Newton steps on the Legendre-series polynomial, for roots accurate to round-off."""
    derivative = legendre.legder(coefficients)
    for _ in range(2):
        roots = roots - legendre.legval(roots, coefficients) / legendre.legval(roots, derivative)
    return roots


class Scheme(ABC):
    """A family of collocation methods; `tableau()` gives the Butcher tableau."""

    stages: int

    def _check_stages(self) -> None:
        if not isinstance(self.stages, int | np.integer) or isinstance(self.stages, bool):
            raise InvalidInput(f"`stages` must be an integer, got {self.stages!r}")
        if not 1 <= self.stages <= _MAX_STAGES:
            raise InvalidInput(
                f"`stages` must lie in 1..{_MAX_STAGES}, got {self.stages}; "
                "FESD uses 1 to 4 stages"
            )

    @property
    @abstractmethod
    def order(self) -> int:
        """The order on smooth problems."""

    @abstractmethod
    def tableau(self) -> Tableau:
        """The Butcher tableau."""


@dataclass(frozen=True)
class RadauIIA(Scheme):
    """Radau IIA collocation with `stages` points, c_s = 1: order 2s - 1, stiffly accurate.

    Reference: Hairer, Wanner, "Solving ODEs II", section IV.5, Table 5.5 and 5.6.
    """

    stages: int = 2

    def __post_init__(self) -> None:
        self._check_stages()

    @property
    def order(self) -> int:
        return 2 * self.stages - 1

    def tableau(self) -> Tableau:
        return _radau(self.stages)


@dataclass(frozen=True)
class GaussLegendre(Scheme):
    """Gauss-Legendre collocation with `stages` points: order 2s, end point not a stage.

    Reference: Hairer, Wanner, "Solving ODEs II", section IV.5, Table 5.1 and 5.2.
    """

    stages: int = 2

    def __post_init__(self) -> None:
        self._check_stages()

    @property
    def order(self) -> int:
        return 2 * self.stages

    def tableau(self) -> Tableau:
        return _gauss(self.stages)


@cache
def _radau(s: int) -> Tableau:
    # Right Radau points on [-1, 1]: zeros of P_s - P_{s-1}, one of them is 1.
    series = np.zeros(s + 1)
    series[s], series[s - 1] = 1.0, -1.0
    x = _refine(np.sort(legendre.legroots(series).real), series)
    x[-1] = 1.0
    return collocation_tableau((x + 1) / 2, 2 * s - 1, f"Radau IIA (s={s})")


@cache
def _gauss(s: int) -> Tableau:
    series = np.zeros(s + 1)
    series[s] = 1.0
    x = _refine(np.sort(legendre.legroots(series).real), series)
    return collocation_tableau((x + 1) / 2, 2 * s, f"Gauss-Legendre (s={s})")


def as_tableau(scheme: object) -> Tableau:
    """The tableau of a `Scheme` (or a `Tableau` itself); anything else raises InvalidInput."""
    if isinstance(scheme, Tableau):
        return scheme
    if isinstance(scheme, Scheme):
        return scheme.tableau()
    raise InvalidInput(
        f"unknown `scheme` {scheme!r}: pass RadauIIA(stages=s), GaussLegendre(stages=s) "
        "or a Tableau"
    )
