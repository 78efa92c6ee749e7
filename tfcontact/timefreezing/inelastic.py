"""Time-freezing for inelastic impacts with Coulomb friction, any number of contacts.

DESIGN.md 4.3-4.4, PROBLEMS.md 0.3, [AUTO23] sections 3-4. State y = (q, v, t).
Per contact i the switching functions are

    c_q,i  = K f_c,i(q)                     (gap; K = `gap_scale`, default 1)
    c_vn,i = n_i(q)^T v                     (normal velocity)
    c_vt,i = b_i(q)^T v                     (planar friction, n_t = 1)
    c_vt,i = ||B_i(q)^T v||_eps - eps_t     (3-D friction, n_t = 2, see below)

with step variables alpha_q,i, alpha_vn,i, alpha_vt,i. The modes are

    f_ODE     = (v, M^{-1} f_v, 1)                        (free flight, clock runs)
    f_n,i     = (0, M^{-1} n_i a_n, 0)                    (frictionless contact)
    planar:  f_+,i = (0, M^{-1} (n_i - mu b_i) a_n, 0)    (v_t > 0)
             f_-,i = (0, M^{-1} (n_i + mu b_i) a_n, 0)    (v_t < 0)
    3-D:     f_+,i = (0, M^{-1} (n_i a_n - B_i mu a_n v_t/||v_t||_eps), 0)   (||v_t|| > eps_t)
             f_-,i = (0, M^{-1} (n_i a_n + B_i v_t), 0)                       (||v_t|| < eps_t)

The 3-D pair is [AUTO23] eq. (26) and section 4.4: exact Coulomb slip for
||v_t|| > eps_t; inside the eps_t-ball lambda_t = v_t pushes ||v_t|| out to eps_t, so
stick is a sliding mode with a velocity drift eps_t. (DESIGN.md 4.4 agrees; nosnoc's
code divides by ||v_t + eps_t|| instead.) To keep every expression and its derivative
finite at v_t = 0 (a ball dropped straight down starts there) the norm is smoothed,
||v_t||_eps = sqrt(v_t^T v_t + eps_t^2), and the switching function is
c_vt = ||v_t||_eps - sqrt(2) eps_t, which is zero exactly on ||v_t|| = eps_t; the
relative error of the slip force is below eps_t^2 / (2 ||v_t||^2).
`Inelastic(friction=InscribedPyramid())` replaces the 3-D pair by planar friction along
each tangent with mu / sqrt(2) (the square inscribed in the cone; `InscribedPyramid`):
linear in v, stick exact, for several feet standing at once (benchmarks/legged.md).

The Heaviside product form (DESIGN.md 4.4) combines the contacts:

    theta_ODE = prod_i (alpha_q,i + alpha_vn,i - alpha_q,i alpha_vn,i)
    theta_+,i = (1 - alpha_q,i)(1 - alpha_vn,i) alpha_vt,i
    theta_-,i = (1 - alpha_q,i)(1 - alpha_vn,i)(1 - alpha_vt,i)
    theta_n,i = (1 - alpha_q,i)(1 - alpha_vn,i)          (mu_i = 0)

so simultaneous impacts add their auxiliary fields while the clock is frozen.

The Heaviside right-hand side is linear in the weights, and every mode's velocity block
is M(q)^{-1} times a generalized force F_k (F_ODE = f_v, F_+,i = n_i a_n - ..., and so
on), so

    sum_k theta_k f_k = (theta_ODE v, M^{-1} sum_k theta_k F_k, theta_ODE)

exactly: one solve with M(q) instead of one per mode (nine for four 3-D contacts). The
`dynamics` strategy chooses the expression handed to the FESD layer: `PerModeSolves`
(default: sum_k theta_k f_k as written), `OneSolve` (one solve) or
`InverseDynamics` (issues 30/31: accelerations a as auxiliary variables of every stage
point, f = (theta_ODE v, a, theta_ODE) and M(q) a = sum_k theta_k F_k, no M^{-1} at all).
All three are the same dynamics, so solutions agree; the derivatives differ in cost
(benchmarks/dynamics_forms.md). The default stays the per-mode form: the measured plans
(hopper, hopper-exact, the reduced monoped chain) follow IPOPT paths that the other forms'
round-off changes, and with `OneSolve` those three failed their tests (a second hop at T,
a failed re-solve). `TimeFreezingSystem.modes` keeps the per-mode columns
either way (diagnostics, plots, tests).

The Stewart form (`form="stewart"`, one contact, planar or no friction) gives each sign
pattern of the switching functions its own region, as nosnoc_py's time-freezing examples
do: the auxiliary fields where c_q < 0 and c_vn < 0 (split by the sign of c_vt), f_ODE in
the others, with Stewart's convex multipliers theta in place of the step variables.
"""

from __future__ import annotations

import itertools
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import casadi as ca
import numpy as np

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.fesd.system import HeavisideSystem, StewartSystem
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact
from tfcontact.timefreezing.system import TimeFreezingSystem


def smooth_norm(vt: ca.SX, eps: float) -> ca.SX:
    """||v_t||_eps = sqrt(v_t^T v_t + eps^2): smooth everywhere, >= eps."""
    return ca.sqrt(ca.sumsqr(vt) + eps**2)


@dataclass(frozen=True)
class DynamicsTerms:
    """What a `HeavisideDynamics` strategy hands to `HeavisideSystem`: the rhs, and the
    auxiliary variables with their equations (empty for an explicit rhs)."""

    rhs: ca.SX
    auxiliary: ca.SX = field(default_factory=lambda: ca.SX(0, 1))
    equations: ca.SX = field(default_factory=lambda: ca.SX(0, 1))


class HeavisideDynamics(ABC):
    """How the Heaviside right-hand side sum_k theta_k f_k is written as an expression.

    Column 0 of `modes` is free flight f_ODE = (v, M^{-1} f_v, 1), weight theta_ODE;
    every other column is (0, M^{-1} F_k, 0). `forces` holds the generalized forces
    (f_v, F_1, ...) in the same order, so the strategies can regroup the sum.
    """

    name: str = "dynamics"
    # False: the strategy adds auxiliary variables, which only the Heaviside form carries
    explicit: ClassVar[bool] = True

    @abstractmethod
    def terms(self, cls: ComplementarityLagrangianSystem, modes: ca.SX, weights: ca.SX,
              forces: ca.SX) -> DynamicsTerms:
        """f(y, u, alpha[, a]), shape (2 n_q + 1, 1), equal to modes @ weights where the
        auxiliary equations hold, as this strategy writes it."""


@dataclass(frozen=True)
class OneSolve(HeavisideDynamics):
    """(theta_ODE v, M^{-1} (sum_k theta_k F_k), theta_ODE): one solve with M(q).

    The sum of the solves is the solve of the sum, so this is the per-mode expression
    regrouped; the NLP's Jacobian and Hessian evaluate one LDL of M(q) instead of one per
    mode (solo12: 9 -> 1, Hessian of lambda^T f about 25 % fewer instructions).
    """

    name: str = "one_solve"

    def terms(self, cls: ComplementarityLagrangianSystem, modes: ca.SX, weights: ca.SX,
              forces: ca.SX) -> DynamicsTerms:
        theta_ode = weights[0]
        return DynamicsTerms(ca.vertcat(
            theta_ode * cls.v, cls.solve_mass(ca.mtimes(forces, weights)), theta_ode))


@dataclass(frozen=True)
class PerModeSolves(HeavisideDynamics):
    """modes @ weights as written: one M(q) solve per mode (the default: the form the
    measured plans were solved with)."""

    name: str = "per_mode_solves"

    def terms(self, cls: ComplementarityLagrangianSystem, modes: ca.SX, weights: ca.SX,
              forces: ca.SX) -> DynamicsTerms:
        return DynamicsTerms(ca.mtimes(modes, weights))


@dataclass(frozen=True)
class InverseDynamics(HeavisideDynamics):
    """Accelerations a (one per velocity) as auxiliary variables of every stage point:

        f = (theta_ODE v, a, theta_ODE),   M(q) a - sum_k theta_k F_k = 0.

    No expression holds M^{-1}: the equation is linear in a and the NLP's derivatives
    are those of M(q) a and of the forces (solo12: Hessian about 2.2x cheaper than
    `OneSolve`'s), for n_v more variables and equalities per stage point. The solutions
    are those of the explicit forms, but IPOPT's path to them is not: on the hopper bench
    the lifted NLPs need many more iterations, and with loose stepping-stone NLPs end in
    a worse local solution (benchmarks/dynamics_forms.md). Opt-in for that reason.
    """

    name: str = "inverse_dynamics"
    explicit: ClassVar[bool] = False

    def terms(self, cls: ComplementarityLagrangianSystem, modes: ca.SX, weights: ca.SX,
              forces: ca.SX) -> DynamicsTerms:
        a = ca.vertcat(*[ca.SX.sym(f"a_{name}") for name in cls.v_names])
        theta_ode = weights[0]
        return DynamicsTerms(
            rhs=ca.vertcat(theta_ode * cls.v, a, theta_ode), auxiliary=a,
            equations=ca.mtimes(cls.mass_matrix, a) - ca.mtimes(forces, weights))


@dataclass(frozen=True)
class FrictionTerms:
    """What a `SpatialFriction` strategy adds for one contact with two tangents: its
    switching functions and step variables (with names), and its auxiliary modes as
    generalized forces F_k, each weighted by (1 - alpha_q)(1 - alpha_vn) * factor_k."""

    switching: tuple[ca.SX, ...]
    alphas: tuple[ca.SX, ...]
    alpha_names: tuple[str, ...]
    forces: tuple[ca.SX, ...]
    factors: tuple[ca.SX, ...]
    mode_names: tuple[str, ...]


class SpatialFriction(ABC):
    """How Coulomb friction of a contact with two tangents (3-D) enters the auxiliary
    dynamics. Planar contacts (one tangent) are the same for every strategy."""

    name: str = "friction"

    @abstractmethod
    def terms(self, contact: Contact, vt: ca.SX) -> FrictionTerms:
        """The contact's friction terms; `vt` = B^T v, its tangential velocity (2,)."""


@dataclass(frozen=True)
class SmoothedCone(SpatialFriction):
    """The circular cone ([AUTO23] eq. (26), module docstring): c_vt = ||v_t||_eps -
    sqrt(2) eps_t, slip f_+ = n a_n - B mu a_n v_t/||v_t||_eps, and inside the eps_t-ball
    f_- = n a_n + B v_t. Slip is exact Coulomb; stick is a sliding mode on ||v_t|| =
    eps_t (the foot creeps at eps_t), and the derivatives grow as 1/eps_t. The default."""

    name: str = "smoothed_cone"

    def terms(self, contact: Contact, vt: ca.SX) -> FrictionTerms:
        a_t = ca.SX.sym(f"alpha_vt_{contact.name}")
        gain = contact.mu * contact.a_n
        norm = smooth_norm(vt, contact.eps_t)
        push = contact.normal * contact.a_n
        tangents = contact.tangents
        return FrictionTerms(
            switching=(norm - math.sqrt(2.0) * contact.eps_t,), alphas=(a_t,),
            alpha_names=(f"vt_{contact.name}",),
            forces=(push - ca.mtimes(tangents, vt) * (gain / norm),
                    push + ca.mtimes(tangents, vt)),
            factors=(a_t, 1 - a_t),
            mode_names=(f"aux_plus_{contact.name}", f"aux_minus_{contact.name}"))


@dataclass(frozen=True)
class InscribedPyramid(SpatialFriction):
    """Planar friction along each tangent b_1, b_2 on its own, with the coefficient
    mu / sqrt(2): the friction set is the square |lambda_tj| <= mu lambda_n / sqrt(2),
    inscribed in Coulomb's cone (DESIGN.md 4.4's polyhedral alternative, PROBLEMS.md 0.3).

    Per tangent a switching function c_vtj = b_j^T v and a step variable alpha_vtj; the
    four modes n a_n -+ g b_1 -+ g b_2 (g = mu a_n / sqrt(2)) carry the weights of the
    sign pairs, so that their sum is n a_n - g (2 alpha_vt1 - 1) b_1 - g (2 alpha_vt2 - 1)
    b_2. Everything is linear in v: the derivatives stay bounded, and stick is the
    sliding mode B^T v = 0 exactly, as in the planar case. The price: a slipping contact
    brakes with mu / sqrt(2) along each tangent it slides along, along the diagonal of
    the square, not against its velocity (maximal dissipation holds only for slip along a
    diagonal, and the verification's check says so); every force is inside the true cone.
    """

    name: str = "inscribed_pyramid"

    def terms(self, contact: Contact, vt: ca.SX) -> FrictionTerms:
        name = contact.name
        a_1, a_2 = ca.SX.sym(f"alpha_vt1_{name}"), ca.SX.sym(f"alpha_vt2_{name}")
        gain = contact.mu * contact.a_n / math.sqrt(2.0)
        push = contact.normal * contact.a_n
        b_1, b_2 = contact.tangents[:, 0] * gain, contact.tangents[:, 1] * gain
        signs = ((1, 1), (1, -1), (-1, 1), (-1, -1))  # sign of (b_1^T v, b_2^T v)
        step = {1: (a_1, a_2), -1: (1 - a_1, 1 - a_2)}
        return FrictionTerms(
            switching=(vt[0], vt[1]), alphas=(a_1, a_2),
            alpha_names=(f"vt1_{name}", f"vt2_{name}"),
            forces=tuple(push - s1 * b_1 - s2 * b_2 for s1, s2 in signs),
            factors=tuple(step[s1][0] * step[s2][1] for s1, s2 in signs),
            mode_names=tuple(f"aux_{'+' if s1 > 0 else '-'}{'+' if s2 > 0 else '-'}_{name}"
                             for s1, s2 in signs))


@dataclass(frozen=True)
class Inelastic:
    """Inelastic impacts (restitution 0) with Coulomb friction; Heaviside-step form.

    The gains a_n and eps_t are per contact (`Contact.a_n`, `Contact.eps_t`).

    Args:
        normal_switching: "separate" (default, [AUTO23]): two switching functions per
            contact, c_q = f_c and c_vn = n^T v, with theta_ODE factor
            alpha_q + alpha_vn - alpha_q alpha_vn; "max": one, c_qv = max(f_c, n^T v)
            (nosnoc's `time_freezing_nonsmooth_switching_fun`), with factor alpha_qv.
            R_1 = {c_qv > 0} and Q = {c_qv < 0} are the same regions, but on the contact
            surface the step variable is unique (the separate pair is only determined
            through its product), which the NLPs may prefer.
        gap_scale: K > 0 [1/s] in the gap's switching function, c_q = K f_c (and
            max(K f_c, n^T v)). The regions, hence the exact solutions, do not depend on
            K, but the relaxed MPCC does: the relaxation bounds the product of each step
            variable with a multiplier in the switching function's units. With K = 1 a gap
            of 1e-4 m is as "closed" as a normal velocity of 1e-4 m/s, and relaxed plans let
            the auxiliary dynamics act while the foot is still above the ground; K of the
            order of 1/h (h a finite element's duration) measures the gap by the velocity
            that closes it within one element (benchmarks/hopper_bench.md).
        form: "heaviside" (default: step variables, any number of contacts) or
            "stewart" (one region per sign pattern of the switching functions, one
            contact with planar or no friction).
        dynamics: how the Heaviside form writes sum_k theta_k f_k (module docstring):
            `PerModeSolves()` (default), `OneSolve()` or `InverseDynamics()`
            (accelerations as auxiliary variables). The Stewart form hands every region's
            mode to FESD separately, so there is nothing to regroup there; it takes the
            explicit strategies and ignores them.
        friction: how contacts with two tangents (3-D) rub: `SmoothedCone()` (default,
            [AUTO23]) or `InscribedPyramid()` (planar friction per tangent, bounded
            derivatives, exact stick). Planar contacts are the same for both.
    """

    normal_switching: str = "separate"
    gap_scale: float = 1.0
    form: str = "heaviside"
    dynamics: HeavisideDynamics = field(default_factory=PerModeSolves)
    friction: SpatialFriction = field(default_factory=SmoothedCone)

    def __post_init__(self) -> None:
        if self.normal_switching not in ("separate", "max"):
            raise InvalidInput(
                f"`normal_switching` must be 'separate' or 'max', got {self.normal_switching!r}"
            )
        if not (math.isfinite(self.gap_scale) and self.gap_scale > 0):
            raise InvalidInput(f"`gap_scale` must be a finite number > 0, got {self.gap_scale!r}")
        if self.form not in ("heaviside", "stewart"):
            raise InvalidInput(f"`form` must be 'heaviside' or 'stewart', got {self.form!r}")
        if not isinstance(self.dynamics, HeavisideDynamics):
            raise InvalidInput("`dynamics` must be a `HeavisideDynamics` strategy such as "
                               f"`OneSolve()`, got {self.dynamics!r}")
        if not isinstance(self.friction, SpatialFriction):
            raise InvalidInput("`friction` must be a `SpatialFriction` strategy: "
                               f"`SmoothedCone()` or `InscribedPyramid()`, got "
                               f"{self.friction!r}")

    def build(self, cls: ComplementarityLagrangianSystem) -> TimeFreezingSystem:
        """The time-freezing PSS of `cls` (module docstring)."""
        bad = [c.name for c in cls.contacts if c.restitution != 0.0]
        if bad:
            raise IncompatibleOptions(
                f"contacts {bad} have restitution > 0 but the `Inelastic` method was chosen: "
                "use `Elastic()` (single frictionless contact) or set restitution = 0"
            )
        if self.form == "stewart":
            if not self.dynamics.explicit:
                raise IncompatibleOptions(
                    f"`dynamics={self.dynamics!r}` adds auxiliary variables, which only the "
                    "Heaviside form carries: use form='heaviside' or an explicit strategy "
                    "such as OneSolve()")
            return self._build_stewart(cls)
        n = cls.n_q
        t = ca.SX.sym("t")
        y = ca.vertcat(cls.q, cls.v, t)
        zeros_q = ca.SX.zeros(n, 1)
        f_ode = ca.vertcat(cls.v, cls.acceleration, 1)
        switching, alphas, alpha_names = [], [], []
        modes, weights, region_names = [f_ode], [], ["ode"]
        theta_ode = ca.SX(1)
        aux_weights, aux_modes, aux_names = [], [], []
        forces = [cls.forces]  # generalized force of each mode, in the order of `modes`
        for i, contact in enumerate(cls.contacts):
            name = contact.name
            normal = contact.normal
            gap = self.gap_scale * contact.gap
            if self.normal_switching == "max":
                a_qv = ca.SX.sym(f"alpha_qv_{name}")
                switching.append(ca.fmax(gap, cls.normal_velocity(i)))
                alphas.append(a_qv)
                alpha_names.append(f"gap_vn_{name}")
                theta_ode = theta_ode * a_qv
                in_q = 1 - a_qv
            else:
                a_q = ca.SX.sym(f"alpha_q_{name}")
                a_n = ca.SX.sym(f"alpha_vn_{name}")
                switching += [gap, cls.normal_velocity(i)]
                alphas += [a_q, a_n]
                alpha_names += [f"gap_{name}", f"vn_{name}"]
                theta_ode = theta_ode * (a_q + a_n - a_q * a_n)
                in_q = (1 - a_q) * (1 - a_n)
            if not contact.has_friction:
                push = normal * contact.a_n
                forces.append(push)
                aux_modes.append(ca.vertcat(zeros_q, cls.solve_mass(push), 0))
                aux_weights.append(in_q)
                aux_names.append(f"aux_n_{name}")
                continue
            vt = cls.tangential_velocity(i)
            if contact.n_tangents == 1:
                a_t = ca.SX.sym(f"alpha_vt_{name}")
                gain = contact.mu * contact.a_n
                friction = FrictionTerms(
                    switching=(vt,), alphas=(a_t,), alpha_names=(f"vt_{name}",),
                    forces=(normal * contact.a_n - contact.tangents * gain,
                            normal * contact.a_n + contact.tangents * gain),
                    factors=(a_t, 1 - a_t),
                    mode_names=(f"aux_plus_{name}", f"aux_minus_{name}"))
            else:
                friction = self.friction.terms(contact, vt)
            switching += friction.switching
            alphas += friction.alphas
            alpha_names += friction.alpha_names
            forces += friction.forces
            aux_modes += [ca.vertcat(zeros_q, cls.solve_mass(force), 0)
                          for force in friction.forces]
            aux_weights += [in_q * factor for factor in friction.factors]
            aux_names += friction.mode_names
        weights = ca.vertcat(theta_ode, *aux_weights)
        modes = ca.horzcat(*modes, *aux_modes)
        region_names += aux_names
        alpha = ca.vertcat(*alphas)
        terms = self.dynamics.terms(cls, modes, weights, ca.horzcat(*forces))
        state_names = (*cls.q_names, *cls.v_names, "t")
        pss = HeavisideSystem(
            x=y, u=cls.u, alpha=alpha, rhs=terms.rhs, switching=ca.vertcat(*switching),
            state_names=state_names, control_names=cls.control_names,
            auxiliary=terms.auxiliary, auxiliary_equations=terms.equations,
        )
        return TimeFreezingSystem(
            pss=pss, kind="inelastic", clock_index=2 * n, q_index=slice(0, n),
            v_index=slice(n, 2 * n), modes=modes, weights=weights,
            region_names=tuple(region_names), cls=cls,
            info=(("form", "heaviside"), ("dynamics", self.dynamics.name),
                  ("alpha_names", tuple(alpha_names)),
                  ("normal_switching", self.normal_switching),
                  ("gap_scale", self.gap_scale), ("friction", self.friction.name),
                  ("a_n", tuple(c.a_n for c in cls.contacts)),
                  ("eps_t", tuple(c.eps_t for c in cls.contacts))),
        )

    def _build_stewart(self, cls: ComplementarityLagrangianSystem) -> TimeFreezingSystem:
        """The Stewart form (module docstring): 2^n_c regions for n_c switching functions."""
        if cls.n_contacts != 1 or cls.contacts[0].n_tangents > 1:
            raise IncompatibleOptions(
                "the Stewart form of `Inelastic` supports one contact with planar or no "
                f"friction; `cls` has {cls.n_contacts} contact(s) with "
                f"{[c.n_tangents for c in cls.contacts]} tangents: use form='heaviside'")
        contact = cls.contacts[0]
        n = cls.n_q
        t = ca.SX.sym("t")
        y = ca.vertcat(cls.q, cls.v, t)
        zeros_q = ca.SX.zeros(n, 1)
        f_ode = ca.vertcat(cls.v, cls.acceleration, 1)
        gap = self.gap_scale * contact.gap
        vn = cls.normal_velocity(0)
        if self.normal_switching == "max":
            switching = [ca.fmax(gap, vn)]
        else:
            switching = [gap, vn]
        n_normal = len(switching)
        normal = contact.normal * contact.a_n
        if contact.has_friction:
            switching.append(cls.tangential_velocity(0))
            slip = contact.tangents * (contact.mu * contact.a_n)
            aux = {1.0: ca.vertcat(zeros_q, cls.solve_mass(normal - slip), 0),
                   -1.0: ca.vertcat(zeros_q, cls.solve_mass(normal + slip), 0)}
        else:
            aux = {1.0: ca.vertcat(zeros_q, cls.solve_mass(normal), 0)}
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=len(switching))))
        modes, names = [], []
        for row in signs:
            if np.all(row[:n_normal] < 0):
                key = row[n_normal] if contact.has_friction else 1.0
                modes.append(aux[key])
                names.append(f"aux_{'plus' if key > 0 else 'minus'}_{contact.name}"
                             if contact.has_friction else f"aux_n_{contact.name}")
            else:
                modes.append(f_ode)
                names.append("ode_" + "".join("+" if c > 0 else "-" for c in row))
        modes = ca.horzcat(*modes)
        state_names = (*cls.q_names, *cls.v_names, "t")
        pss = StewartSystem.from_sign_matrix(
            y, cls.u, modes, ca.vertcat(*switching), signs,
            state_names=state_names, control_names=cls.control_names,
        )
        return TimeFreezingSystem(
            pss=pss, kind="inelastic", clock_index=2 * n, q_index=slice(0, n),
            v_index=slice(n, 2 * n), modes=modes, region_names=tuple(names), cls=cls,
            info=(("form", "stewart"), ("normal_switching", self.normal_switching),
                  ("gap_scale", self.gap_scale), ("a_n", (contact.a_n,)),
                  ("eps_t", (contact.eps_t,))),
        )
