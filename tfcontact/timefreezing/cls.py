"""Complementarity Lagrangian systems (CLS): the input of the time-freezing builder.

A CLS with n_c unilateral point contacts (DESIGN.md 4.3, [AUTO23] eq. (20)):

    q' = v,
    M(q) v' = f_v(q, v, u) + sum_i (n_i(q) lambda_n,i + B_i(q) lambda_t,i),
    0 <= lambda_n,i  perp  f_c,i(q) >= 0,
    lambda_t,i in argmin { -v^T B_i lambda : ||lambda|| <= mu_i lambda_n,i }   (Coulomb),
    n_i^T v+ = -e_i n_i^T v-  at an impact of contact i (Newton restitution).

Here f_v = B_u u - h(q, v) is a generalised *force* [N, N m] (controls, gravity,
Coriolis); the paper's f_v is the acceleration M^{-1} f_v. Everything is a CasADi SX
expression of the symbols q, v, u; nothing is solved here.

References: Nurkanovic, Albrecht, Brogliato, Diehl, "The time-freezing reformulation
for numerical optimal control of complementarity Lagrangian systems with state jumps",
Automatica 158 (2023) 111295 [AUTO23].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.symbolic import as_sx, check_depends, labels


def _symbol_vector(expr: object, name: str) -> ca.SX:
    expr = as_sx(expr, name)
    if expr.numel() == 0:
        return ca.SX(0, 1)
    if expr.shape[1] != 1 or not expr.is_valid_input():
        raise InvalidInput(
            f"`{name}` must be a column of pure symbols (casadi.SX.sym), got shape {expr.shape}"
        )
    return expr


@dataclass(frozen=True, eq=False)
class Contact:
    """One unilateral point contact of a CLS.

    Args:
        gap: f_c(q) [m], scalar SX expression of q; f_c >= 0 is admissible.
        normal: n(q), column in R^{n_v}: the generalised normal direction (n^T v is the
            normal velocity [m/s]). `None` means grad_q f_c, filled in by the CLS.
        tangents: B(q), shape (n_v, n_t) with n_t in {0, 1, 2}: the tangential directions
            (B^T v is the tangential velocity [m/s]). `None` means no tangent (n_t = 0).
        mu: Coulomb friction coefficient [-], >= 0. mu > 0 needs n_t >= 1.
        restitution: Newton restitution e in [0, 1] [-]; 0 = inelastic impact.
        a_n: gain of the inelastic auxiliary dynamics [m/s^2 per unit normal], > 0
            ([AUTO23] Prop. 3; nosnoc's default 100).
        eps_t: 3-D friction regularisation [m/s], > 0 ([AUTO23] eq. (26); default 1e-7):
            stick is a sliding mode on ||v_t|| = eps_t.
        name: label used in state and switching-function names.
    """

    gap: ca.SX
    normal: ca.SX | None = None
    tangents: ca.SX | None = None
    mu: float = 0.0
    restitution: float = 0.0
    a_n: float = 100.0
    eps_t: float = 1e-7
    name: str = "contact"

    def __post_init__(self) -> None:
        for arg in ("mu", "restitution", "a_n", "eps_t"):
            value = getattr(self, arg)
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise InvalidInput(f"`{arg}` must be a number, got {value!r}")
            if not math.isfinite(value):
                raise InvalidInput(f"`{arg}` must be finite, got {value!r}")
        if self.mu < 0:
            raise InvalidInput(
                f"`mu` must be >= 0 (Coulomb friction coefficient), got {self.mu}; "
                "use mu = 0 for a frictionless contact"
            )
        if not 0.0 <= self.restitution <= 1.0:
            raise InvalidInput(
                f"`restitution` must be in [0, 1], got {self.restitution}; "
                "0 is an inelastic impact, 1 a perfectly elastic one"
            )
        if self.a_n <= 0:
            raise InvalidInput(
                f"`a_n` must be > 0 (auxiliary normal gain [m/s^2]), got {self.a_n}; "
                "nosnoc's default is 100"
            )
        if self.eps_t <= 0:
            raise InvalidInput(
                f"`eps_t` must be > 0 (3-D friction regularisation [m/s]), got {self.eps_t}; "
                "the default is 1e-7"
            )
        gap = as_sx(self.gap, "gap")
        if gap.numel() != 1:
            raise InvalidInput(f"`gap` must be a scalar expression, got shape {gap.shape}")
        object.__setattr__(self, "gap", gap)
        if self.normal is not None:
            normal = as_sx(self.normal, "normal")
            if normal.shape[1] != 1:
                raise InvalidInput(f"`normal` must be a column, got shape {normal.shape}")
            object.__setattr__(self, "normal", normal)
        tangents = ca.SX(0, 0) if self.tangents is None else as_sx(self.tangents, "tangents")
        if tangents.shape[1] > 2:
            raise InvalidInput(
                f"`tangents` must have 0, 1 or 2 columns (planar or 3-D contact), "
                f"got shape {tangents.shape}"
            )
        object.__setattr__(self, "tangents", tangents)
        if self.mu > 0 and tangents.shape[1] == 0:
            raise InvalidInput(
                f"contact `{self.name}` has `mu` = {self.mu} but no `tangents`: give B(q) "
                "with 1 (planar) or 2 (3-D) columns, or set mu = 0"
            )

    @property
    def n_tangents(self) -> int:
        """n_t: 0 (frictionless), 1 (planar) or 2 (3-D)."""
        return self.tangents.shape[1]

    @property
    def has_friction(self) -> bool:
        return self.mu > 0 and self.n_tangents > 0


@dataclass(frozen=True, eq=False)
class ComplementarityLagrangianSystem:
    """A CLS q' = v, M(q) v' = f_v(q, v, u) + contact forces (module docstring).

    Args:
        q: configuration symbols, shape (n_q, 1). n_q must equal n_v.
        v: velocity symbols, shape (n_v, 1).
        u: control symbols, shape (n_u, 1); may be empty (`casadi.SX(0, 1)`).
        mass_matrix: M(q), shape (n_v, n_v), symmetric positive definite [kg, kg m^2].
        forces: f_v(q, v, u) = B_u u - h(q, v), shape (n_v, 1) [N, N m].
        contacts: the contacts (at least one).
        q_names, v_names, control_names: labels (defaults q0.., v0.., u0..).

    Raises:
        InvalidInput: shapes disagree, an expression depends on foreign symbols, a gap does
            not depend on q, or a normal has the wrong size.
    """

    q: ca.SX
    v: ca.SX
    u: ca.SX
    mass_matrix: ca.SX
    forces: ca.SX
    contacts: tuple[Contact, ...]
    q_names: tuple[str, ...] | None = None
    v_names: tuple[str, ...] | None = None
    control_names: tuple[str, ...] | None = None
    _functions: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        q = _symbol_vector(self.q, "q")
        v = _symbol_vector(self.v, "v")
        u = _symbol_vector(self.u, "u")
        if q.numel() == 0:
            raise InvalidInput("`q` is empty: a CLS needs at least one coordinate")
        if q.numel() != v.numel():
            raise InvalidInput(
                f"`q` has {q.numel()} entries but `v` has {v.numel()}: time-freezing needs "
                "n_q == n_v (use a minimal coordinate set, e.g. a ZYX-Euler free flyer)"
            )
        n = q.numel()
        mass = as_sx(self.mass_matrix, "mass_matrix")
        if mass.shape != (n, n):
            raise InvalidInput(f"`mass_matrix` must have shape ({n}, {n}), got {mass.shape}")
        forces = as_sx(self.forces, "forces")
        if forces.shape != (n, 1):
            raise InvalidInput(f"`forces` must have shape ({n}, 1), got {forces.shape}")
        check_depends(mass, [q], "mass_matrix", "q")
        check_depends(forces, [q, v, u], "forces", "q, v and u")
        if isinstance(self.contacts, Contact):
            raise InvalidInput("`contacts` must be a sequence of Contact, e.g. (contact,)")
        contacts = tuple(self.contacts)
        if not contacts:
            raise InvalidInput("`contacts` is empty: a CLS needs at least one contact")
        resolved = []
        for i, contact in enumerate(contacts):
            if not isinstance(contact, Contact):
                raise InvalidInput(
                    f"`contacts[{i}]` must be a Contact, got {type(contact).__name__}"
                )
            where = f"contacts[{i}]"
            check_depends(contact.gap, [q], f"{where}.gap", "q")
            if not ca.depends_on(contact.gap, q):
                raise InvalidInput(
                    f"`{where}.gap` = {contact.gap} does not depend on `q` (contact "
                    f"`{contact.name}`): a gap must be a function f_c(q) of the configuration"
                )
            normal = contact.normal
            if normal is None:
                normal = ca.jacobian(contact.gap, q).T
            if normal.shape != (n, 1):
                raise InvalidInput(f"`{where}.normal` must have shape ({n}, 1), got {normal.shape}")
            check_depends(normal, [q], f"{where}.normal", "q")
            tangents = contact.tangents
            if tangents.shape[1] > 0:
                if tangents.shape[0] != n:
                    raise InvalidInput(
                        f"`{where}.tangents` must have {n} rows, got shape {tangents.shape}"
                    )
                check_depends(tangents, [q], f"{where}.tangents", "q")
            resolved.append(replace(contact, normal=normal))
        names = [c.name for c in resolved]
        if len(set(names)) != len(names):
            resolved = [replace(c, name=f"{c.name}{i}") for i, c in enumerate(resolved)]
        for name, value in (("q", q), ("v", v), ("u", u), ("mass_matrix", mass),
                            ("forces", forces), ("contacts", tuple(resolved))):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "q_names", labels(self.q_names, n, "q", "q_names"))
        object.__setattr__(self, "v_names", labels(self.v_names, n, "v", "v_names"))
        object.__setattr__(
            self, "control_names", labels(self.control_names, u.numel(), "u", "control_names")
        )

    # ------------------------------------------------------------------ sizes

    @property
    def n_q(self) -> int:
        return self.q.numel()

    @property
    def n_u(self) -> int:
        return self.u.numel()

    @property
    def n_contacts(self) -> int:
        return len(self.contacts)

    # ------------------------------------------------------------------ expressions

    def solve_mass(self, rhs: ca.SX) -> ca.SX:
        """M(q)^{-1} rhs: a numeric inverse when M is constant, else a symbolic sparse
        LDL^T factorisation of M(q) (never an explicit inverse)."""
        if not ca.depends_on(self.mass_matrix, self.q):
            inverse = np.linalg.inv(np.asarray(ca.DM(ca.evalf(self.mass_matrix))))
            return ca.mtimes(ca.DM(inverse), rhs)
        if "ldl" not in self._functions:  # sparse symbolic LDL^T of M(q), built once
            self._functions["ldl"] = ca.ldl(self.mass_matrix)
        d, lt, p = self._functions["ldl"]
        return ca.ldl_solve(rhs, d, lt, p)

    @property
    def acceleration(self) -> ca.SX:
        """M(q)^{-1} f_v(q, v, u) [m/s^2]: the free-flight acceleration."""
        return self.solve_mass(self.forces)

    def delassus(self, i: int) -> ca.SX:
        """D_i(q) = n_i^T M^{-1} n_i (DESIGN.md 4.3)."""
        n = self.contacts[i].normal
        return ca.mtimes(n.T, self.solve_mass(n))

    def normal_velocity(self, i: int) -> ca.SX:
        """n_i(q)^T v [m/s]."""
        return ca.mtimes(self.contacts[i].normal.T, self.v)

    def tangential_velocity(self, i: int) -> ca.SX:
        """v_t,i = B_i(q)^T v [m/s], shape (n_t, 1)."""
        return ca.mtimes(self.contacts[i].tangents.T, self.v)

    def phi(self, i: int) -> ca.SX:
        """phi_i = n^T M^{-1} f_v + d/dq(n^T v) v: the free normal acceleration [m/s^2].

        [AUTO23] eq. (11b); contact i persists while phi_i <= 0 and breaks when phi_i > 0.
        """
        n = self.contacts[i].normal
        vn = ca.mtimes(n.T, self.v)
        return ca.mtimes(n.T, self.acceleration) + ca.mtimes(ca.jacobian(vn, self.q), self.v)

    def gamma(self, i: int) -> ca.SX:
        """gamma_i = D a_n / (D a_n - phi): the slow-down of time on persistent contact.

        [AUTO23] Theorem 4, eq. (17); valid while phi_i <= 0.
        """
        d_an = self.delassus(i) * self.contacts[i].a_n
        return d_an / (d_an - self.phi(i))

    def function(self, name: str) -> ca.Function:
        """Numeric CasADi functions (cached): `mass` M(q), `forces` f_v(q, v, u),
        `gaps` (n_c,), `normals` (n_v, n_c), `tangents_i` B_i(q), `painleve_margins`
        (n_c,): n_i^T M^-1 n_i - mu_i ||B_i^T M^-1 n_i||, the normal acceleration per unit
        normal force of contact i slipping in its worst direction. Where it is negative
        the frictional contact is ill-posed (Painleve): a slip there has no unique force,
        and time-freezing's auxiliary dynamics M^-1 (n - mu B d) a_n drive the contact
        further in instead of out."""
        cache = self._functions
        if name not in cache:
            q, v, u = self.q, self.v, self.u
            if name == "mass":
                cache[name] = ca.Function("mass", [q], [self.mass_matrix])
            elif name == "forces":
                cache[name] = ca.Function("forces", [q, v, u], [self.forces])
            elif name == "gaps":
                gaps = ca.vertcat(*[c.gap for c in self.contacts])
                cache[name] = ca.Function("gaps", [q], [gaps])
            elif name == "normals":
                cache[name] = ca.Function(
                    "normals", [q], [ca.horzcat(*[c.normal for c in self.contacts])]
                )
            elif name == "painleve_margins":
                margins = []
                for c in self.contacts:
                    minv_n = self.solve_mass(c.normal)
                    margin = ca.mtimes(c.normal.T, minv_n)
                    if c.has_friction:
                        margin -= c.mu * ca.norm_2(ca.mtimes(c.tangents.T, minv_n))
                    margins.append(margin)
                cache[name] = ca.Function(name, [q], [ca.vertcat(*margins)])
            elif name.startswith("tangents_"):
                i = int(name.split("_")[1])
                cache[name] = ca.Function(name, [q], [self.contacts[i].tangents])
            else:
                raise InvalidInput(f"unknown function `{name}`")
        return cache[name]


Cls = ComplementarityLagrangianSystem
"""Short alias of `ComplementarityLagrangianSystem`."""
