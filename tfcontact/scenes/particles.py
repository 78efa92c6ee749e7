"""Small contact models with closed-form answers: point masses, a ball, a rod.

Reference problems for the time-freezing layer's tests and benchmarks (PROBLEMS.md
TF-4, TF-7, [AUTO23] Example 3). Each builder returns a
`ComplementarityLagrangianSystem`; the closed forms are functions next to them.
Units: m, s, kg; g = 9.81 m/s^2 unless given.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.timefreezing.cls import ComplementarityLagrangianSystem, Contact

G = 9.81


def point_mass(
    dim: int = 2,
    *,
    mu: float = 0.0,
    restitution: float = 0.0,
    a_n: float = 100.0,
    eps_t: float = 1e-7,
    mass: float = 1.0,
    gravity: float = G,
    controlled: bool = False,
) -> ComplementarityLagrangianSystem:
    """A point mass above the ground q_dim >= 0 (the last coordinate is the height).

    q = (x, [y,] z) [m], v [m/s]; M = m I; f_v = (u) - (0, .., m g). dim = 1 is the bouncing
    ball of TF-7, dim = 2 the particle of [AUTO23] Example 1 / TF-3, dim = 3 the 3-D
    friction case of TF-4. With `controlled`, u in R^dim is a force [N].
    """
    if dim not in (1, 2, 3):
        raise InvalidInput(f"`dim` must be 1, 2 or 3, got {dim!r}")
    axes = "xyz"[3 - dim:] if dim < 3 else "xyz"
    if dim == 2:
        axes = "xz"
    q = ca.SX.sym("q", dim)
    v = ca.SX.sym("v", dim)
    u = ca.SX.sym("u", dim) if controlled else ca.SX(0, 1)
    weight = ca.DM.zeros(dim, 1)
    weight[dim - 1] = -mass * gravity
    forces = weight + (u if controlled else 0)
    tangents = ca.SX(ca.DM.eye(dim)[:, : dim - 1]) if dim > 1 else None
    contact = Contact(gap=q[dim - 1], tangents=tangents, mu=mu, restitution=restitution,
                      a_n=a_n, eps_t=eps_t, name="ground")
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=ca.SX(mass * ca.DM.eye(dim)), forces=ca.SX(forces),
        contacts=(contact,), q_names=tuple(f"q_{a}" for a in axes),
        v_names=tuple(f"v_{a}" for a in axes),
        control_names=tuple(f"u_{a}" for a in axes) if controlled else None,
    )


def rod(
    *, length: float = 1.0, mass: float = 1.0, a_n: float = 100.0, gravity: float = G,
    controlled: bool = False,
) -> ComplementarityLagrangianSystem:
    """A planar rod q = (x, z, theta) with two end-point contacts on the ground.

    Ends at z -+ (L/2) sin(theta); M = diag(m, m, m L^2/12); frictionless, inelastic.
    Dropped flat (theta = 0) both ends hit at once: a simultaneous impact.
    With `controlled`, u = (F_x, F_z, torque) acts on the centre of mass.
    """
    q = ca.SX.sym("q", 3)
    v = ca.SX.sym("v", 3)
    u = ca.SX.sym("u", 3) if controlled else ca.SX(0, 1)
    half = length / 2
    inertia = mass * length**2 / 12
    mass_matrix = ca.SX(ca.DM(np.diag([mass, mass, inertia])))
    forces = ca.vertcat(0, -mass * gravity, 0) + (u if controlled else 0)
    left = Contact(gap=q[1] - half * ca.sin(q[2]), a_n=a_n, name="left")
    right = Contact(gap=q[1] + half * ca.sin(q[2]), a_n=a_n, name="right")
    return ComplementarityLagrangianSystem(
        q=q, v=v, u=u, mass_matrix=mass_matrix, forces=ca.SX(forces), contacts=(left, right),
        q_names=("x", "z", "theta"), v_names=("v_x", "v_z", "omega"),
    )


def painleve_rod(
    *, mu: float, length: float = 1.0, mass: float = 2.0, a_n: float = 100.0,
    gravity: float = G,
) -> ComplementarityLagrangianSystem:
    """Painleve's rod: q = (x, z, theta), touching the ground with its lower end at
    z - (L/2) sin(theta), Coulomb friction mu, M = diag(m, m, m L^2/12), inelastic.

    Its `painleve_margins` are (1 + 3 cos^2 theta - 3 mu |sin theta cos theta|) / m: for
    mu > 4/3 a band of angles makes the frictional contact ill-posed.
    """
    q = ca.SX.sym("q", 3)
    half = length / 2
    end_x = q[0] - half * ca.cos(q[2])
    contact = Contact(gap=q[1] - half * ca.sin(q[2]), tangents=ca.jacobian(end_x, q).T,
                      mu=mu, a_n=a_n, name="end")
    return ComplementarityLagrangianSystem(
        q=q, v=ca.SX.sym("v", 3), u=ca.SX(0, 1),
        mass_matrix=ca.SX(ca.DM(np.diag([mass, mass, mass * length**2 / 12]))),
        forces=ca.vertcat(0, -mass * gravity, 0), contacts=(contact,),
        q_names=("x", "z", "theta"), v_names=("v_x", "v_z", "omega"),
    )


def drop_time(height: float, gravity: float = G) -> float:
    """Free-fall time sqrt(2 h / g) [s] from rest at height h [m]."""
    return math.sqrt(2.0 * height / gravity)


def bounce_apexes(height: float, restitution: float, n: int) -> np.ndarray:
    """Apex heights h e^{2k}, k = 1..n, of a ball dropped from rest at height h [m]."""
    return height * restitution ** (2 * np.arange(1, n + 1))


def bounce_times(height: float, restitution: float, n: int, gravity: float = G) -> np.ndarray:
    """Impact times [s] of a ball dropped from rest at h: t_1 = sqrt(2h/g),
    t_{k+1} = t_k + 2 e^k sqrt(2h/g)."""
    t1 = drop_time(height, gravity)
    gaps = 2 * t1 * restitution ** np.arange(1, n)
    return t1 + np.concatenate([[0.0], np.cumsum(gaps)])


def coulomb_slide(v0: float, mu: float, t: np.ndarray | float, gravity: float = G,
                  push: float = 0.0, mass: float = 1.0) -> np.ndarray:
    """Speed [m/s] of a block sliding on the ground with initial speed v0 > 0 under a push
    force F = push [N] along the motion and Coulomb friction mu m g: decelerates at
    mu g - F/m until it stops, and then stays stopped when F <= mu m g."""
    t = np.asarray(t, dtype=float)
    accel = push / mass - mu * gravity
    if accel >= 0:
        return v0 + accel * t
    return np.maximum(v0 + accel * t, 0.0)


def exact_sliding_particle(
    tau: float, *, height: float, vx0: float, mu: float, a_n: float, gravity: float = G
) -> np.ndarray:
    """The exact time-freezing solution y(tau) = (q_x, q_z, v_x, v_z, t) of a unit point
    mass dropped from rest height `height` with horizontal speed vx0 > 0 onto ground with
    Coulomb friction mu, inelastic impact, auxiliary gain a_n (planar builder).

    Free fall until tau_1 = sqrt(2h/g); frozen while v_z rises at a_n to 0 (the friction
    auxiliary field reduces v_x at mu a_n, clamped at 0); then on the contact surface the
    clock runs at gamma = a_n/(a_n + g) and v_x decreases at mu g per unit of physical time
    until it stops (stick, a sliding mode with v_x = 0).
    """
    t1 = drop_time(height, gravity)
    v_imp = gravity * t1
    if tau <= t1:
        return np.array([vx0 * tau, height - 0.5 * gravity * tau**2, vx0, -gravity * tau, tau])
    x1 = vx0 * t1
    frozen = v_imp / a_n
    if tau <= t1 + frozen:
        s = tau - t1
        vx = max(vx0 - mu * a_n * s, 0.0)
        return np.array([x1, 0.0, vx, -v_imp + a_n * s, t1])
    gamma = a_n / (a_n + gravity)
    vx_post = max(vx0 - mu * v_imp, 0.0)
    t = t1 + gamma * (tau - t1 - frozen)
    s = t - t1
    stop = vx_post / (mu * gravity) if mu > 0 else np.inf
    s_slide = min(s, stop)
    vx = vx_post - mu * gravity * s_slide
    return np.array([x1 + vx_post * s_slide - 0.5 * mu * gravity * s_slide**2, 0.0, vx, 0.0, t])


def exact_bouncing_ball(
    tau: float, *, height: float, restitution: float, stiffness: float, gravity: float = G
) -> np.ndarray:
    """The exact elastic time-freezing solution y(tau) = (q, v, t) of a 1-D ball dropped
    from rest at `height`: free flights and, inside the ground, the damped oscillator
    q'' = -k q - c_d q' with frozen clock (`tfcontact.timefreezing.elastic`)."""
    from tfcontact.timefreezing.elastic import elastic_damping

    c_d = elastic_damping(restitution, stiffness) if restitution < 1 else 0.0
    omega = math.sqrt(stiffness - c_d**2 / 4)
    frozen = math.pi / omega
    q, v, t, clock_tau = height, 0.0, 0.0, 0.0  # state at numerical time clock_tau
    while True:
        # free flight from (q, v) until q = 0 going down
        flight = (v + math.sqrt(v**2 + 2 * gravity * q)) / gravity
        if tau <= clock_tau + flight:
            s = tau - clock_tau
            return np.array([q + v * s - 0.5 * gravity * s**2, v - gravity * s, t + s])
        clock_tau += flight
        t += flight
        v_in = v - gravity * flight
        if tau <= clock_tau + frozen:
            s = tau - clock_tau  # q(s) = (v_in/omega) e^{-c s/2} sin(omega s)
            decay = math.exp(-c_d * s / 2)
            qs = v_in / omega * decay * math.sin(omega * s)
            vs = v_in * decay * (math.cos(omega * s) - c_d / (2 * omega) * math.sin(omega * s))
            return np.array([qs, vs, t])
        clock_tau += frozen
        q, v = 0.0, -restitution * v_in
