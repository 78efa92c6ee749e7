"""Time-freezing for elastic impacts (Newton restitution e in (0, 1]), one contact.

DESIGN.md 4.2, PROBLEMS.md 0.2, [CSL21] (Nurkanovic, Sartor, Albrecht, Diehl, IEEE
CSL 2021). State y = (q, v, t), one switching function c = f_c(q), two regions:

    f_1 = (v, M^{-1} f_v, 1)                                      c > 0 (free flight)
    f_2 = (n v_n / (n^T n),  M^{-1} n (-k f_c - c_d v_n) / D,  0)  c < 0 (frozen)

with v_n = n^T v and D = n^T M^{-1} n. Inside the obstacle the pair
(f_c, v_n) obeys d f_c/dtau = v_n, d v_n/dtau = -k f_c - c_d v_n (exactly for a gap
affine in q, up to the curvature term (dn/dtau)^T v otherwise): a damped oscillator
that leaves the obstacle after half a period pi / omega_d, omega_d = sqrt(k - c_d^2/4),
with v_n+ = -exp(-c_d pi / (2 omega_d)) v_n- = -e v_n- for

    c_d = 2 |ln e| sqrt(k / (pi^2 + ln^2 e))        (c_d = 0 for e = 1).

The tangential velocity B^T v is unchanged when B is kinetically orthogonal to n
(B^T M^{-1} n = 0). nosnoc's `cls_elastic.m` builds the same oscillator from
J_n^T q and J_n^T M^{-1} v, which equals this one for M = I and a gap J_n^T q.
Stewart form: indicators g = (-c, c).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.fesd.system import StewartSystem
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem
from tfcontact.timefreezing.system import TimeFreezingSystem


def elastic_damping(restitution: float, stiffness: float) -> float:
    """c_d = 2 |ln e| sqrt(k / (pi^2 + ln^2 e)) [1/s]: the damping that makes the
    oscillator's exit normal velocity -e times its entry velocity."""
    log_e = math.log(restitution)
    return 2.0 * abs(log_e) * math.sqrt(stiffness / (math.pi**2 + log_e**2))


def frozen_duration(restitution: float, stiffness: float) -> float:
    """Numerical time [s] of one elastic impact: half a damped period pi / omega_d."""
    c = elastic_damping(restitution, stiffness)
    return math.pi / math.sqrt(stiffness - c**2 / 4.0)


def normal_spring(
    cls: ComplementarityLagrangianSystem, index: int, *, stiffness: float, damping: float
) -> tuple[ca.SX, ca.SX]:
    """The auxiliary spring-damper of contact `index` along its normal (module docstring).

    (q', v') = (n v_n / (n^T n), M^{-1} n (-k f_c - c_d v_n) / D), with n, f_c, v_n and
    D = n^T M^{-1} n of that contact: inside the obstacle (f_c, v_n) is a damped oscillator.
    The clock row (0) is the caller's; a scene with several walls sums these fields.

    Args:
        cls: the CLS.
        index: the contact.
        stiffness: k [1/s^2 in numerical time], > 0.
        damping: c_d [1/s], >= 0 (`elastic_damping(e, k)`).

    Returns:
        (q', v') as SX columns in `cls.q`, `cls.v`.
    """
    if not 0 <= index < cls.n_contacts:
        raise InvalidInput(f"`index` must be in [0, {cls.n_contacts}), got {index!r}")
    contact = cls.contacts[index]
    normal = contact.normal
    vn = cls.normal_velocity(index)
    qdot = normal * vn / ca.sumsqr(normal)
    vdot = cls.solve_mass(normal) * ((-stiffness * contact.gap - damping * vn)
                                     / cls.delassus(index))
    return qdot, vdot


@dataclass(frozen=True)
class Elastic:
    """Elastic impacts with restitution from the contact; Stewart form, one contact.

    Args:
        stiffness: k of the auxiliary spring [1/s^2 in numerical time], > 0
            (nosnoc's default k_aux = 10; TF-7 uses 100). A larger k shortens the frozen
            piece (pi / sqrt(k) for e = 1) but stiffens the equations.
    """

    stiffness: float = 10.0

    def __post_init__(self) -> None:
        if not (isinstance(self.stiffness, int | float) and math.isfinite(self.stiffness)
                and self.stiffness > 0):
            raise InvalidInput(
                f"`stiffness` must be a finite number > 0, got {self.stiffness!r}; "
                "nosnoc's default is 10"
            )

    def build(self, cls: ComplementarityLagrangianSystem) -> TimeFreezingSystem:
        """The elastic time-freezing PSS of `cls` (module docstring)."""
        if cls.n_contacts != 1:
            raise IncompatibleOptions(
                f"elastic time-freezing supports one contact, `cls` has {cls.n_contacts}: "
                "use restitution 0 (`Inelastic()`) for several contacts"
            )
        contact = cls.contacts[0]
        if contact.mu > 0:
            raise IncompatibleOptions(
                f"elastic time-freezing has no friction model, contact `{contact.name}` has "
                f"mu = {contact.mu}: set mu = 0 or restitution = 0"
            )
        if contact.restitution <= 0:
            raise IncompatibleOptions(
                f"contact `{contact.name}` has restitution {contact.restitution}: "
                "the `Elastic` method needs e in (0, 1]; use `Inelastic()` for e = 0"
            )
        e = contact.restitution
        k = float(self.stiffness)
        c_d = elastic_damping(e, k)
        n = cls.n_q
        t = ca.SX.sym("t")
        y = ca.vertcat(cls.q, cls.v, t)
        f_ode = ca.vertcat(cls.v, cls.acceleration, 1)
        qdot, vdot = normal_spring(cls, 0, stiffness=k, damping=c_d)
        f_aux = ca.vertcat(qdot, vdot, 0)
        modes = ca.horzcat(f_ode, f_aux)
        state_names = (*cls.q_names, *cls.v_names, "t")
        pss = StewartSystem.from_sign_matrix(
            y, cls.u, modes, contact.gap, np.array([[1.0], [-1.0]]),
            state_names=state_names, control_names=cls.control_names,
        )
        return TimeFreezingSystem(
            pss=pss, kind="elastic", clock_index=2 * n, q_index=slice(0, n),
            v_index=slice(n, 2 * n), modes=modes, region_names=("ode", f"aux_{contact.name}"),
            cls=cls,
            info=(("stiffness", k), ("damping", c_d), ("restitution", e),
                  ("frozen_duration", frozen_duration(e, k))),
        )
