"""MPCC relaxations: how the complementarity products G_i H_i enter the NLP.

Each relaxation is one class that supplies its own extra variables, constraints
and objective term as functions of the homotopy parameter sigma (DESIGN.md 4.7):

* `Scholtes`:   G_i H_i <= sigma                               (Scholtes 2001)
* `L1Penalty`:  f + (1/sigma) sum_i G_i H_i
* `LinfPenalty`: f + (1/sigma) s,  G_i H_i <= s,  s >= 0       (l_inf elastic mode)

sigma -> 0 recovers the MPCC; the penalties are exact for sigma small enough.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class RelaxedTerms:
    """What a relaxation adds to the NLP: variables, constraints, objective term."""

    w: ca.SX  # extra variables
    lbw: np.ndarray
    ubw: np.ndarray
    w0: np.ndarray
    g: ca.SX  # extra constraints
    lbg: np.ndarray
    ubg: np.ndarray
    objective: ca.SX  # added to f


class Relaxation(ABC):
    """A way of relaxing 0 <= G perp H >= 0 with a parameter sigma > 0."""

    name: str = "relaxation"

    @abstractmethod
    def terms(self, products: ca.SX, sigma: ca.SX) -> RelaxedTerms:
        """The relaxation of `products` = G * H (elementwise) for the parameter `sigma`."""


def _empty() -> tuple[ca.SX, np.ndarray]:
    return ca.SX(0, 1), np.zeros(0)


@dataclass(frozen=True)
class Scholtes(Relaxation):
    """G_i H_i <= sigma: a smooth NLP for every sigma > 0 (Scholtes, SIAM J. Optim. 2001)."""

    name: str = "scholtes"

    def terms(self, products: ca.SX, sigma: ca.SX) -> RelaxedTerms:
        w, e = _empty()
        n = products.numel()
        return RelaxedTerms(
            w=w, lbw=e, ubw=e, w0=e,
            g=products - sigma, lbg=np.full(n, -np.inf), ubg=np.zeros(n),
            objective=ca.SX(0),
        )


@dataclass(frozen=True)
class L1Penalty(Relaxation):
    """f + (1/sigma) sum_i G_i H_i: no extra constraints, many small products."""

    name: str = "l1_penalty"

    def terms(self, products: ca.SX, sigma: ca.SX) -> RelaxedTerms:
        w, e = _empty()
        return RelaxedTerms(
            w=w, lbw=e, ubw=e, w0=e, g=ca.SX(0, 1), lbg=e, ubg=e,
            objective=ca.sum1(products) / sigma,
        )


@dataclass(frozen=True)
class LinfPenalty(Relaxation):
    """f + (1/sigma) s with G_i H_i <= s: one elastic variable bounds every product.

    Args:
        s_max: upper bound of the elastic variable s.
    """

    s_max: float = 10.0
    name: str = "linf_penalty"

    def __post_init__(self) -> None:
        if not self.s_max > 0:
            from tfcontact.errors import InvalidInput

            raise InvalidInput(f"`s_max` must be positive, got {self.s_max}")

    def terms(self, products: ca.SX, sigma: ca.SX) -> RelaxedTerms:
        s = ca.SX.sym("s_elastic")
        n = products.numel()
        return RelaxedTerms(
            w=s, lbw=np.zeros(1), ubw=np.array([self.s_max]), w0=np.array([min(1.0, self.s_max)]),
            g=products - s, lbg=np.full(n, -np.inf), ubg=np.zeros(n),
            objective=s / sigma,
        )


# The relaxations by the short names scripts and command lines use.
RELAXATIONS: dict[str, type[Relaxation]] = {
    "scholtes": Scholtes, "l1": L1Penalty, "linf": LinfPenalty,
}
