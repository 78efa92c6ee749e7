"""The monoped (Capler leg) task of PROBLEMS.md TF-9, [AUTO23] section 6, as data.

The robot is the project's URDF `robots/monoped.urdf` on a planar x-z base:
q = (q_x, q_z, phi_hip, phi_knee), controls u = (hip torque, knee torque) [N m].
The task: start standing at q0 = (0, 0.4, 0, 0), reach q(T) = (3, 0.4, 0, 0) in T = 2.5 s,
minimise int u^T u dt, never put the foot into one of the holes, modelled as ellipses
in the x-z plane that the foot must stay outside of:

    ((p_foot,x - x_c,k) / a)^2 + (p_foot,z / b)^2 >= 1,   a = 0.5 m, b = 0.1 m.

TF-9 treats the foot as a point: the gap is p_foot,z. The URDF's foot is a sphere of
radius 0.028 m on the frame `foot`, so the contact candidate is
`ContactSpec("foot", 0.028)` against `Ground(height=-0.028)`, whose gap
p_foot,z - 0.028 + 0.028 is exactly TF-9's.

`monoped_problem(task)` returns the robot, its time-freezing system and the
`ContactProblem` (tfcontact.ocp.contact), initialised as [AUTO23] does: zero controls and
the start state at every node (no contact schedule).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.ocp.contact import ContactProblem
from tfcontact.ocp.goals import EndPosition, LiftOffs, Moves
from tfcontact.ocp.problem import Constraint
from tfcontact.robot import ContactSpec, Ground, Hole, Plane, Robot, Terrain, load_robot
from tfcontact.timefreezing import Inelastic, TimeFreezingSystem, from_robot, time_freeze

FOOT_RADIUS = 0.028
"""Radius of the URDF's foot sphere [m]; the ground is lowered by it (point-foot gap)."""


HOLE_FORMS = ("ellipse", "bump", "terrain")
"""How a `MonopedTask` models its holes (`MonopedTask.hole_form`)."""


@dataclass(frozen=True)
class MonopedTask:
    """Data of a TF-9 task (defaults: the [AUTO23] version).

    Args:
        horizon: physical horizon T [s].
        n_intervals: control intervals N.
        q0: start configuration (q_x [m], q_z [m], phi_hip [rad], phi_knee [rad]).
        q_goal: terminal configuration, imposed as an equality.
        holes: centres x_c,k [m] of the elliptic holes.
        hole_half_width, hole_depth: the ellipse semi-axes a, b [m].
        control_bound: |u_i| <= control_bound [N m].
        mu: Coulomb friction coefficient; a_n: time-freezing auxiliary gain [1/s^2].
        gap_scale: K [1/s] of the gap's switching function K f_c (`Inelastic.gap_scale`).
        speed_of_time: (s_min, s_max).
        stagewise_clock: t = k T / N at every control-interval boundary (else only at T).
        hole_form: "ellipse": ((p_x - x_c)/a)^2 + (p_z/b)^2 >= 1 (TF-9); "bump":
            p_z >= b (1 - ((p_x - x_c)/a)^2), the parabola under the ellipse's top half,
            whose gradient in p_z never vanishes (the ellipse's does at p_z = 0, where a
            foot on the ground at a hole's edge gets stuck in a locally infeasible point);
            "terrain": the holes are the terrain's (`tfcontact.robot.Hole`, bottomless,
            rims rounded by `hole_rounding`): no support over |p_x - x_c| < a, where the
            foot may dip below the ground, and no path constraint on the foot's height
            (the gap against the terrain keeps it out of the ground elsewhere).
        hole_rounding: the rim radius [m] of terrain holes.
        lift_height: the task's check counts a hop where the foot rises above this [m];
            one hop per hole is asked (and the base x at the goal's, within 5 cm).
    """

    horizon: float = 2.5
    n_intervals: int = 20
    q0: tuple[float, float, float, float] = (0.0, 0.4, 0.0, 0.0)
    q_goal: tuple[float, float, float, float] = (3.0, 0.4, 0.0, 0.0)
    holes: tuple[float, ...] = (0.5, 1.5, 2.5)
    hole_half_width: float = 0.5
    hole_depth: float = 0.1
    control_bound: float = 60.0
    mu: float = 0.8
    a_n: float = 200.0
    speed_of_time: tuple[float, float] = (1.0, 25.0)
    stagewise_clock: bool = True
    hole_form: str = "ellipse"
    gap_scale: float = 1.0
    lift_height: float = 0.05
    hole_rounding: float = 0.01

    def __post_init__(self) -> None:
        if self.hole_form not in HOLE_FORMS:
            raise InvalidInput(f"`hole_form` must be one of {', '.join(map(repr, HOLE_FORMS))}, "
                               f"got {self.hole_form!r}")
        for name in ("q0", "q_goal"):
            if len(getattr(self, name)) != 4:
                raise InvalidInput(
                    f"`{name}` must be (q_x, q_z, phi_hip, phi_knee), got {getattr(self, name)!r}")
        for name in ("horizon", "hole_half_width", "hole_depth", "control_bound", "a_n"):
            if not getattr(self, name) > 0:
                raise InvalidInput(f"`{name}` must be positive, got {getattr(self, name)!r}")


def hole_profile(task: MonopedTask, x_c: float, n_points: int = 32) -> np.ndarray:
    """The region of the x-z plane that the foot's centre must stay out of, around the
    hole at x_c, as a convex polygon (n, 2) of (x, z) [m] in counterclockwise order.

    "ellipse": points on ((x - x_c)/a)^2 + (z/b)^2 = 1. "bump": the parabola
    z = b (1 - ((x - x_c)/a)^2) over |x - x_c| <= a (apex included), closed at z = -b:
    the constraint leaves everything below the parabola forbidden, the depth b is for
    drawing only.
    """
    a, b = task.hole_half_width, task.hole_depth
    if task.hole_form == "ellipse":
        angle = np.linspace(0.0, 2 * np.pi, n_points, endpoint=False)
        return np.column_stack([x_c + a * np.cos(angle), b * np.sin(angle)])
    s = np.linspace(1.0, -1.0, n_points - 2 - (n_points % 2 == 0))  # odd: the apex
    return np.vstack([np.column_stack([x_c + a * s, b * (1 - s**2)]),
                      [[x_c - a, -b], [x_c + a, -b]]])


REDUCED_TASK = MonopedTask(horizon=1.0, n_intervals=10, q_goal=(1.0, 0.4, 0.0, 0.0),
                           holes=(0.5,), hole_half_width=0.25, hole_form="bump",
                           speed_of_time=(1.0, 5.0), stagewise_clock=False)
"""A reduced task for tests: one hole (x in [0.25, 0.75]), T = 1 s, N = 10."""

FULL_TASK = MonopedTask(hole_form="bump", speed_of_time=(1.0, 5.0), stagewise_clock=False)
"""[AUTO23]'s task as `scripts/monoped.py` and `tfcontact plan monoped` solve it: the
holes as bumps (from the start-everywhere guess the ellipses end locally infeasible, with
the foot parked on a hole's edge), speed of time in [1, 5] and the clock constrained at T
only, as in the authors' `robot_ocp.m` (benchmarks/monoped_settings.md)."""

MONOPED_TASKS = {"full": FULL_TASK, "reduced": REDUCED_TASK}


def monoped_task(name: str = "full") -> MonopedTask:
    """The named TF-9 task: "full" (`FULL_TASK`) or "reduced" (`REDUCED_TASK`).

    Raises:
        InvalidInput: an unknown name.
    """
    if name not in MONOPED_TASKS:
        raise InvalidInput(f"unknown monoped task {name!r}; tasks: {', '.join(MONOPED_TASKS)}")
    return MONOPED_TASKS[name]


def monoped_options(name: str = "full"):
    """The solver settings of a monoped plan (`ContactSolverOptions`).

    Both tasks: Scholtes from sigma_0 = 1 down to a residual of 1e-4 (the hopper's), IPOPT's
    monotone barrier update (with the adaptive one the reduced task's second NLP ran for
    over 7 minutes), 1000 iterations per NLP. "full" uses Radau IIA with 3 stages (order 5,
    as [AUTO23]); "reduced" 2 stages (with 3 its homotopy ends infeasible; with 2 it
    converged on an earlier machine and reaches the iteration cap on another). Neither
    gives a verified plan yet (benchmarks/monoped_settings.md).

    Raises:
        InvalidInput: an unknown name.
    """
    from tfcontact.fesd import RadauIIA
    from tfcontact.mpcc import Homotopy, Ipopt, Scholtes
    from tfcontact.ocp.contact import ContactSolverOptions

    monoped_task(name)  # an unknown name raises here
    return ContactSolverOptions(
        scheme=RadauIIA(3 if name == "full" else 2), n_finite_elements=3,
        relaxation=Scholtes(),
        homotopy=Homotopy(sigma_0=1.0, kappa=0.1, tolerance=1e-4, max_nlps=6),
        nlp=Ipopt(tol=1e-8, max_iter=1000, options={"mu_strategy": "monotone"}),
    )


@dataclass(frozen=True, eq=False)
class MonopedProblem:
    """The loaded robot, its time-freezing system, the OCP and the kinematic functions.

    Attributes:
        task: the `MonopedTask`.
        robot: the loaded `Robot` (with the foot contact candidate).
        ground: the `Ground` (lowered by the foot radius), or with terrain holes the
            `Terrain` (that plane minus the holes).
        system: `time_freeze(from_robot(robot, ground, mu, a_n))`.
        problem: the `ContactProblem`.
        knee, foot: CasADi functions q -> (x, z) of the knee and foot centre [m].
    """

    task: MonopedTask
    robot: Robot
    ground: Ground | Terrain
    system: TimeFreezingSystem
    problem: ContactProblem
    knee: ca.Function
    foot: ca.Function

    def scene(self) -> dict:
        """The scene of the plan's trajectory sidecar: the lowered ground and the holes,
        each with its `hole_profile` (what the replay draws); with terrain holes the
        terrain of primitives (`Terrain.to_dict`)."""
        task = self.task
        if isinstance(self.ground, Terrain):
            return {"terrain": self.ground.to_dict(),
                    "note": "the foot sphere (radius 0.028 m) rests on the ground lowered "
                            "by its radius; the holes are the terrain's"}
        return {
            "terrain": {"type": "flat", "height": float(self.ground.height),
                        "normal": [float(c) for c in self.ground.normal]},
            "holes": [{"x_c": c, "half_width": task.hole_half_width, "depth": task.hole_depth,
                       "form": task.hole_form, "profile": hole_profile(task, c).tolist()}
                      for c in task.holes],
            "note": "the foot sphere (radius 0.028 m) rests on the ground lowered by its "
                    "radius: the gap is TF-9's point-foot gap p_foot,z",
        }

    def hole_values(self, q: np.ndarray) -> np.ndarray:
        """((p_x - x_c) / a)^2 + (p_z / b)^2 - 1 per hole at configurations q (n, 4) -> (n, k);
        >= 0 outside the holes (TF-9's ellipses; for terrain holes a diagnostic only: the
        foot may pass below them)."""
        p = np.asarray(self.foot(np.atleast_2d(q).T)).T
        a, b = self.task.hole_half_width, self.task.hole_depth
        return np.stack([((p[:, 0] - c) / a) ** 2 + (p[:, 1] / b) ** 2 - 1.0
                         for c in self.task.holes], axis=1).reshape(len(p), -1)


def _goals(task: MonopedTask, x_name: str) -> tuple:
    """The task checks: the base x at the goal's, one hop per hole, and motion when the
    goal differs from the start (a task without holes may stand still)."""
    goals = [EndPosition(x_name, task.q_goal[0], 0.05)]
    if task.holes:
        goals.append(LiftOffs(0, len(task.holes), task.lift_height))
    if not np.allclose(task.q0, task.q_goal):
        goals.append(Moves())
    return tuple(goals)


def monoped_problem(task: MonopedTask | str = "full") -> MonopedProblem:
    """Build TF-9's OCP for the project's monoped URDF.

    State bounds ([AUTO23] section 6): q_x >= -0.05, 0.2 <= q_z <= 0.55,
    |phi_hip| <= 3 pi / 8, |phi_knee| <= pi / 2. Path constraints at every stage point:
    p_foot,x, p_knee,x >= -0.05; p_knee,z >= 0.05; -0.005 <= p_foot,z <= 0.2; the holes
    (with `hole_form` "terrain" the terrain's instead, and no lower bound on p_foot,z).
    Terminal constraint q(T) = q_goal; cost int u^T u dt (physical time). `task` may be a
    `MonopedTask` or a name of `monoped_task`.
    """
    task = monoped_task(task) if isinstance(task, str) else task
    robot = load_robot("monoped", base="planar_xz",
                       contacts=(ContactSpec("foot", FOOT_RADIUS),))
    a, b = task.hole_half_width, task.hole_depth
    ground: Ground | Terrain = Ground(height=-FOOT_RADIUS)
    if task.hole_form == "terrain":
        ground = Terrain((Plane(height=-FOOT_RADIUS, friction=task.mu),
                          *(Hole(x=(c - a, c + a), rounding=task.hole_rounding)
                            for c in task.holes)))
    cls = from_robot(robot, ground, mu=task.mu, a_n=task.a_n)
    system = time_freeze(cls, method=Inelastic(gap_scale=task.gap_scale))
    q_sym = robot.twin.q
    knee = ca.Function("knee", [q_sym], [robot.twin.frame_position("shank")[[0, 2]]])
    foot = ca.Function("foot", [q_sym], [robot.twin.frame_position("foot")[[0, 2]]])
    y, u = system.y, system.u
    q = y[system.q_index]
    p_knee = knee(q)
    p_foot = foot(q)
    foot_floor = -0.005
    if task.hole_form == "ellipse":
        holes = [((p_foot[0] - c) / a) ** 2 + (p_foot[1] / b) ** 2 for c in task.holes]
        hole_lower = [1.0] * len(holes)
    elif task.hole_form == "bump":
        holes = [p_foot[1] - b * (1 - ((p_foot[0] - c) / a) ** 2) for c in task.holes]
        hole_lower = [0.0] * len(holes)
    else:  # the terrain has the holes, and its gap keeps the foot out of the ground
        holes, hole_lower, foot_floor = [], [], -np.inf
    path_expr = ca.vertcat(p_foot[0], p_knee[0], p_knee[1], p_foot[1], *holes)
    path_lower = [-0.05, -0.05, 0.05, foot_floor] + hole_lower
    path_upper = [np.inf, np.inf, np.inf, 0.2] + [np.inf] * len(holes)
    problem = ContactProblem(
        system=system, q0=np.array(task.q0), v0=np.zeros(4), horizon=task.horizon,
        n_intervals=task.n_intervals, running_cost=ca.sumsqr(u),
        u_lower=-task.control_bound, u_upper=task.control_bound,
        q_lower=[-0.05, 0.2, -3 * np.pi / 8, -np.pi / 2],
        q_upper=[np.inf, 0.55, 3 * np.pi / 8, np.pi / 2],
        speed_of_time=task.speed_of_time, stagewise_clock=task.stagewise_clock,
        path=Constraint(path_expr, path_lower, path_upper),
        terminal=Constraint(q, np.array(task.q_goal), np.array(task.q_goal)),
        goals=_goals(task, cls.q_names[0]),
    )
    return MonopedProblem(task=task, robot=robot, ground=ground, system=system,
                          problem=problem, knee=knee, foot=foot)
