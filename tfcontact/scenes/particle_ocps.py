"""Reference contact OCPs with balls and particles (PROBLEMS.md TF-1, TF-2, TF-3).

Each builder returns a `tfcontact.ocp.contact.ContactProblem` (physical time, the
time-freezing system inside) that `solve_contact` solves. Shared by the scripts
`scripts/plan_ball_in_box.py`, `scripts/plan_throwing_ball.py`,
`scripts/plan_particle_friction.py` and by `tests/test_plans_particles.py`.
Units: m, s, kg, N.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.fesd import GaussLegendre
from tfcontact.mpcc import Homotopy, Ipopt, LinfPenalty
from tfcontact.ocp.contact import ContactProblem, ContactSolverOptions
from tfcontact.ocp.problem import Constraint
from tfcontact.robot import ContactSpec, RobotSpec
from tfcontact.scenes.ball_in_box import TF2_WALLS, ball_in_box, circle_reference
from tfcontact.scenes.particles import G, point_mass
from tfcontact.timefreezing import Elastic, time_freeze

BALL_RADIUS = 0.05  # [m], robots/ball.urdf
# How the plans' point masses are drawn: the project's ball on an x-z base.
BALL_ROBOT = RobotSpec(source="ball", base="planar_xz",
                       contacts=(ContactSpec("ball", BALL_RADIUS),))
# The point mass touches the ground with its centre: the ball's floor lies a radius lower.
BALL_GROUND = {"terrain": {"type": "flat", "height": -BALL_RADIUS}}

def box_circle_problem(
    omega: float = math.pi,
    *,
    radius: float = 1.0,
    periods: float = 2.0,
    n_intervals: int = 25,
    max_force: float = 50.0,
    stiffness: float = 100.0,
    walls: tuple[float, float, float, float] = TF2_WALLS,
    speed_of_time: tuple[float, float] = (1.0, 25.0),
    numerical_horizon: float | None = None,
) -> ContactProblem:
    """The seed's 2-D ball in a box tracking a circle (PROBLEMS.md TF-2, the issue's form).

    min int_0^T ||q - q_ref(t)||^2 + ||v - v_ref(t)||^2 dt with the circle
    q_ref = R (cos w t, sin w t), v_ref = q_ref' (`circle_reference`, evaluated at the
    clock t), T = periods 2 pi / |w| [s], ||u||^2 <= max_force^2, gravity off, elastic
    walls (e = 1, spring k = `stiffness`), starting on the circle: q0 = (R, 0),
    v0 = (0, R w); the initial guess is the reference. Exact tracking needs the force
    R w^2 [N]: above `max_force` the ball cannot follow the circle and turns on the walls
    (R = 1, 50 N: w = 3 pi needs 88.8 N), below it the optimum (cost 0) touches no wall
    (w = pi: 9.9 N; w = 2 pi: 39.5 N).

    The ball must end inside the box, gaps(q(T)) >= 0: a wall's auxiliary spring runs
    inside the wall while the clock stands still, and without this constraint the plans
    ended mid-bounce at t = T, up to 0.3 m inside a wall (measured).
    """
    if not (math.isfinite(omega) and omega != 0):
        raise InvalidInput(f"`omega` must be a non-zero angular speed [rad/s], got {omega!r}")
    tf = ball_in_box(walls, stiffness=stiffness, restitution=1.0, gravity=0.0)
    y, u = tf.y, tf.u
    t = y[tf.clock_index]
    (qx, qy), (vx, vy) = circle_reference(t, radius=radius, omega=omega)
    q, v = y[tf.q_index], y[tf.v_index]
    cost = (q[0] - qx) ** 2 + (q[1] - qy) ** 2 + (v[0] - vx) ** 2 + (v[1] - vy) ** 2
    horizon = periods * 2 * math.pi / abs(omega)
    # initial guess: the reference itself at the interval boundaries
    t_k = np.linspace(0.0, horizon, n_intervals + 1)
    (gx, gy), (gvx, gvy) = circle_reference(t_k, radius=radius, omega=omega)
    cls = tf.cls
    gaps = ca.substitute(ca.vertcat(*[c.gap for c in cls.contacts]), cls.q, q)
    return ContactProblem(
        system=tf, q0=[radius, 0.0], v0=[0.0, radius * omega], horizon=horizon,
        n_intervals=n_intervals, running_cost=cost,
        path=Constraint(ca.sumsqr(u), -np.inf, max_force**2),
        terminal=Constraint(gaps, 0.0, np.inf),
        guess=np.column_stack([gx, gy, gvx, gvy]),
        speed_of_time=speed_of_time, numerical_horizon=numerical_horizon,
    )


# MUMPS's workspace for the box plans' KKT factorisations [% over its estimate]. IPOPT's
# default, 1000, has MUMPS allocate eleven times its estimate for every factorisation:
# 50 made each IPOPT iteration of the w = 3 pi NLP about 18 % cheaper with the same
# iterates (MUMPS enlarges the workspace itself when delayed pivots need more).
BOX_MUMPS_MEM_PERCENT = 50


def box_circle_options() -> ContactSolverOptions:
    """The solver settings of the box plans (`box_circle_problem`, w = pi and 3 pi).

    Gauss-Legendre collocation with 2 stages (order 4, symmetric: it does not damp the wall
    spring, which Radau IIA's damping let the optimiser exploit), N_FE = 3, the l_inf
    penalty from sigma_0 = 0.1 (the plan starts on the reference; benchmarks/
    plans_particles.md), homotopy tolerance 1e-7, IPOPT tolerance 1e-8.

    Chosen for speed by `scripts/bench_ball_in_box.py` (benchmarks/ball_in_box_speed.md),
    against the seed's settings (kappa = 0.1, IPOPT's defaults otherwise): sigma shrinks
    by kappa = 0.05 per NLP (0.1, 5e-3, 2.5e-4), and MUMPS gets `BOX_MUMPS_MEM_PERCENT` %
    workspace instead of IPOPT's 1000 %. The w = 3 pi plan then takes 524 IPOPT
    iterations instead of 612, each up to 18 % cheaper, and reaches the same plan
    (objective 21.63, 8 bounces, end-state deviation 1.6e-7 from the exact four-wall
    replay). Which local solution a homotopy reaches, and in how many iterations, depends
    on round-off: from five starts (the reference, and moved by 1e-9 m) these settings
    took 519-574 iterations, the seed's 612-1190. Tried and left out: MUMPS's AMD
    ordering (each iteration of the third NLP twice as dear), warm starting
    the later NLPs from the multipliers (`Ipopt(warm_start_push=1e-9)`: 457-883) and
    `alpha_for_y = "min"` (333-606 with the warm start, but the w = pi plan then ends on
    a spurious bouncing local minimum). The w = pi plan converges in its first NLP, so
    kappa does not change it.
    """
    return ContactSolverOptions(
        scheme=GaussLegendre(2), n_finite_elements=3, relaxation=LinfPenalty(),
        homotopy=Homotopy(sigma_0=0.1, kappa=0.05, tolerance=1e-7),
        nlp=Ipopt(tol=1e-8, max_iter=2000,
                  options={"mumps_mem_percent": BOX_MUMPS_MEM_PERCENT}))


def throwing_ball_problem(
    target: tuple[float, float] = (4.0, 0.5),
    *,
    horizon: float = 4.0,
    n_intervals: int = 20,
    max_force: float = 9.0,
    restitution: float = 0.9,
    stiffness: float = 10.0,
    terminal_weight: float = 100.0,
    speed_of_time: tuple[float, float] = (1.0, 25.0),
    numerical_horizon: float | None = None,
) -> ContactProblem:
    """TF-1: the throwing ball (elastic ground, e = 0.9, k_aux = 10).

    q = (x, z) [m], v' = u - (0, g); from q0 = (0, 0.5) at rest to q(T) = `target` at
    T = 4 s with ||u|| <= 9 N < m g: the ball cannot fly there on its own force and must
    bounce. Cost int u^T u dt + 100 v(T)^T v(T).
    """
    cls = point_mass(2, restitution=restitution, controlled=True)
    tf = time_freeze(cls, method=Elastic(stiffness))
    y, u = tf.y, tf.u
    v = y[tf.v_index]
    target = np.asarray(target, float)
    return ContactProblem(
        system=tf, q0=[0.0, 0.5], v0=[0.0, 0.0], horizon=horizon, n_intervals=n_intervals,
        running_cost=ca.sumsqr(u), terminal_cost=terminal_weight * ca.sumsqr(v),
        path=Constraint(ca.sumsqr(u), -np.inf, max_force**2),
        terminal=Constraint(y[tf.q_index], target, target),
        speed_of_time=speed_of_time, numerical_horizon=numerical_horizon,
    )


def particle_friction_problem(
    target: tuple[float, float, float, float] = (3.0, 0.0, 0.0, 0.0),
    *,
    horizon: float = 2.0,
    n_intervals: int = 20,
    max_force: float = 10.0,
    mu: float = 0.6,
    a_n: float = G,
) -> ContactProblem:
    """TF-3: an inelastic particle with friction, pushed horizontally.

    q = (x, z) [m], u_x in [-10, 10] N (u_z fixed at 0), v' = (u_x, -g); ground z >= 0,
    e = 0, mu = 0.6, a_n = g (the time-freezing gain, `a_n`); from (0, 1.5, 0, 0) to
    x(T) = (3, 0, 0, 0) at T = 2 s; cost int u_x^2 dt; speed of time in [0.99, 10] (the
    reference implementation's values).
    """
    cls = point_mass(2, mu=mu, a_n=a_n, controlled=True)
    tf = time_freeze(cls)
    y, u = tf.y, tf.u
    state = ca.vertcat(y[tf.q_index], y[tf.v_index])
    target = np.asarray(target, float)
    return ContactProblem(
        system=tf, q0=[0.0, 1.5], v0=[0.0, 0.0], horizon=horizon, n_intervals=n_intervals,
        running_cost=u[0] ** 2, u_lower=[-max_force, 0.0], u_upper=[max_force, 0.0],
        speed_of_time=(0.99, 10.0), terminal=Constraint(state, target, target),
    )
