"""The hopper task of PROBLEMS.md TF-8 (nosbench HOPOCP), as data.

q = (x, z, theta, l): base position, leg angle and leg length. The short task jumps
from x = 0.1 to x_goal with one flight phase; the long task does two jumps. The
reference is a cubic spline through the listed way points, sampled in physical time.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline

from tfcontact.errors import InvalidInput


@dataclass(frozen=True)
class HopperTask:
    """Data of one hopper task (TF-8); states are (q, v) in R^8.

    Args:
        name: "short" or "long" or "bench".
        horizon: physical horizon T [s].
        n_intervals: control intervals N.
        mu: friction coefficient.
        a_n: time-freezing auxiliary gain.
        gap_scale: K [1/s] of the gap's switching function K f_c (`Inelastic.gap_scale`):
            about the inverse of a finite element's duration, so that a relaxed
            complementarity cannot start the impact while the foot is above the ground.
        waypoints: states the reference spline passes through, equally spaced in time.
        state_weights, terminal_weights, control_weights: least-squares weights.
        lower, upper: state box (q, v).
        control_bound: |u_i| <= control_bound for (hip torque [N m], leg force [N]).
        goal_tolerance: the task is done when the base x ends within this of the last
            way point's x [m] ...
        lift_offs, lift_height: ... and the foot rose above `lift_height` [m] at least
            `lift_offs` separate times (the hops happened).
    """

    name: str
    horizon: float
    n_intervals: int
    mu: float
    a_n: float
    waypoints: tuple[tuple[float, ...], ...]
    state_weights: tuple[float, ...]
    terminal_weights: tuple[float, ...]
    control_weights: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    control_bound: float = 50.0
    gap_scale: float = 30.0
    goal_tolerance: float = 0.05
    lift_offs: int = 1
    lift_height: float = 0.05

    def __post_init__(self) -> None:
        if len(self.waypoints) < 2:
            raise InvalidInput("`waypoints` needs at least a start and an end state")
        for w in self.waypoints:
            if len(w) != 8:
                raise InvalidInput(f"each way point must have 8 entries (q, v), got {len(w)}")

    @property
    def x0(self) -> np.ndarray:
        return np.asarray(self.waypoints[0], dtype=float)

    @property
    def x_end(self) -> np.ndarray:
        return np.asarray(self.waypoints[-1], dtype=float)

    def starting_at(self, state: np.ndarray) -> HopperTask:
        """The same task from another start state (q, v): its reference spline begins
        there and passes through the same later way points, so a start moved ahead of or
        behind the first way point is not pulled back to it."""
        state = np.asarray(state, dtype=float)
        if state.shape != (8,) or not np.all(np.isfinite(state)):
            raise InvalidInput(f"a hopper start state is 8 finite numbers (q, v), got "
                               f"shape {state.shape}")
        return replace(self, waypoints=(tuple(float(s) for s in state), *self.waypoints[1:]))

    def reference(self, t: np.ndarray) -> np.ndarray:
        """The reference states at physical times t, shape (len(t), 8)."""
        knots = np.linspace(0.0, self.horizon, len(self.waypoints))
        spline = CubicSpline(knots, np.asarray(self.waypoints, dtype=float))
        return spline(np.clip(np.asarray(t, dtype=float), 0.0, self.horizon))


_Q = (50.0, 50.0, 20.0, 50.0, 0.1, 0.1, 0.1, 0.1)
_Q_T = (300.0, 300.0, 300.0, 300.0, 0.1, 0.1, 0.1, 0.1)
_ZERO_V = (0.0, 0.0, 0.0, 0.0)
# State box (q, v): only the largest base x differs between the tasks.
_LOWER = (0.0, 0.0, -np.pi, 0.1, -10, -10, -5, -5)


def _upper(x_max: float) -> tuple[float, ...]:
    return (x_max, 1.5, np.pi, 0.5, 10, 10, 5, 5)


def hopper_task(name: str = "short") -> HopperTask:
    """The TF-8 tasks: "short" (one jump, T = 1.5), "long" (two jumps, T = 2) and "bench"
    (nosnoc_py's one-hop example: T = 1, x_goal = 1, mid height 1, Q = 100 on positions)."""
    if name == "short":
        return HopperTask(
            name="short", horizon=1.5, n_intervals=20, mu=0.45, a_n=100.0,
            waypoints=((0.1, 0.5, 0.0, 0.5) + _ZERO_V, (0.4, 0.8, 0.0, 0.1) + _ZERO_V,
                       (0.7, 0.5, 0.0, 0.5) + _ZERO_V),
            state_weights=_Q, terminal_weights=_Q_T, control_weights=(0.01, 0.01),
            lower=_LOWER,
            upper=_upper(0.8),
        )
    if name == "long":
        return HopperTask(
            name="long", horizon=2.0, n_intervals=30, mu=1.0, a_n=25.0,
            waypoints=((0.1, 0.5, 0.0, 0.5) + _ZERO_V, (0.4, 0.65, 0.0, 0.2) + _ZERO_V,
                       (0.6, 0.5, 0.0, 0.5) + _ZERO_V, (0.9, 0.65, 0.0, 0.2) + _ZERO_V,
                       (1.3, 0.5, 0.0, 0.5) + _ZERO_V),
            state_weights=_Q, terminal_weights=_Q_T, control_weights=(0.001, 0.001),
            lower=_LOWER,
            upper=_upper(2.0), lift_offs=2,
        )
    if name == "bench":
        return HopperTask(
            name="bench", horizon=1.0, n_intervals=20, mu=0.45, a_n=100.0,
            waypoints=((0.1, 0.5, 0.0, 0.5) + _ZERO_V, (0.55, 1.0, 0.0, 0.1) + _ZERO_V,
                       (1.0, 0.5, 0.0, 0.5) + _ZERO_V),
            state_weights=(100.0, 100.0, 20.0, 50.0, 0.1, 0.1, 0.1, 0.1),
            terminal_weights=_Q_T, control_weights=(0.01, 0.01),
            lower=_LOWER,
            upper=_upper(1.1),
        )
    raise InvalidInput(f"unknown hopper task `{name}`; use `short`, `long` or `bench`")


FOOT_RADIUS = 0.02  # [m], the collision sphere of robots/hopper.urdf
NO_SLIP_GAIN = 100.0  # [m/s^2], K of the no-slip path constraint v_t^2 <= K f_c


def hopper_robot():
    """The hopper of robots/hopper.urdf with the TF-8 coordinates q = (x, z, pitch, l).

    The hip is locked so that the leg angle is the base pitch (theta = -pitch in TF-8's
    sign convention); the ground is lowered by the foot radius so that the gap is TF-8's
    point-foot gap z - l cos(pitch).
    """
    from tfcontact.robot import ContactSpec, Ground, load_robot

    robot = load_robot("hopper", base="planar", locked_joints=("hip_joint",),
                       contacts=(ContactSpec("foot", FOOT_RADIUS),))
    return robot, Ground(height=-FOOT_RADIUS)


def hopper_cls(robot, ground, task: HopperTask):
    """The hopper's CLS: u = (hip torque on the leg angle [N m], leg force [N]).

    As in TF-8 the hip torque acts on the leg angle directly (the body's attitude is not
    modelled), here as a generalised force on the base pitch; the leg force is the
    prismatic joint's force.
    """
    import casadi as ca

    from tfcontact.timefreezing import ComplementarityLagrangianSystem
    from tfcontact.timefreezing.from_robot import from_robot

    leg = from_robot(robot, ground, mu=task.mu, a_n=task.a_n, actuated=("leg_joint",))
    u = ca.SX.sym("u", 2)
    pitch = ca.DM([0.0, 0.0, 1.0, 0.0])
    forces = ca.substitute(leg.forces, leg.u, u[1]) + pitch * u[0]
    return ComplementarityLagrangianSystem(
        q=leg.q, v=leg.v, u=u, mass_matrix=leg.mass_matrix, forces=forces,
        contacts=leg.contacts, q_names=("x", "z", "pitch", "l"),
        v_names=("v_x", "v_z", "v_pitch", "v_l"), control_names=("u_hip", "u_leg"),
    )


def hopper_problem(task: HopperTask | str = "short", *, ground=None):
    """The hopper OCP of TF-8 from the URDF: returns (robot, ground, ContactProblem).

    `ground`: a `tfcontact.robot.Ground` or `Terrain` instead of the flat ground lowered
    by the foot radius (scripts/hopper_step.py: a step).

    The running cost tracks the reference spline evaluated at the *clock* t (piecewise
    linear between the N + 1 control-grid samples: finer sampling only inflates the NLP)
    with weights Q, plus R on the controls; the terminal cost Q_T pulls x(T) to the last
    way point.
    """
    import casadi as ca

    from tfcontact.ocp import Constraint
    from tfcontact.ocp.contact import ContactProblem
    from tfcontact.ocp.goals import EndPosition, LiftOffs, Moves
    from tfcontact.timefreezing import Inelastic, time_freeze

    task = hopper_task(task) if isinstance(task, str) else task
    robot, flat = hopper_robot()
    ground = flat if ground is None else ground
    cls = hopper_cls(robot, ground, task)
    tf = time_freeze(cls, method=Inelastic(gap_scale=task.gap_scale))
    y, u = tf.y, tf.u
    x = ca.vertcat(y[tf.q_index], y[tf.v_index])
    clock = y[tf.clock_index]
    samples = np.linspace(0.0, task.horizon, task.n_intervals + 1)
    reference = task.reference(samples)
    x_ref = ca.vertcat(*[ca.pw_lin(clock, ca.DM(samples), ca.DM(reference[:, i]))
                         for i in range(8)])
    error = x - x_ref
    running = (ca.mtimes([error.T, ca.diag(ca.DM(task.state_weights)), error])
               + ca.mtimes([u.T, ca.diag(ca.DM(task.control_weights)), u]))
    final_error = x - ca.DM(task.x_end)
    terminal = ca.mtimes([final_error.T, ca.diag(ca.DM(task.terminal_weights)), final_error])
    lower, upper = np.asarray(task.lower), np.asarray(task.upper)
    # The task asks for hops, not slides: the foot may not slip while it touches the
    # ground. nosnoc's hopper imposes this as a path complementarity (v_t perp contact);
    # here as v_t^2 <= K f_c, which forces v_t = 0 at f_c = 0 and leaves the foot free
    # in flight (K = 100 m/s^2: 1 m/s of foot speed allowed at 1 cm height).
    contact = cls.contacts[0]
    slip = ca.mtimes(contact.tangents.T, cls.v)
    no_slip = Constraint(slip[0] ** 2 - NO_SLIP_GAIN * contact.gap, upper=0.0)
    problem = ContactProblem(
        system=tf, q0=task.x0[:4], v0=task.x0[4:], horizon=task.horizon,
        n_intervals=task.n_intervals, running_cost=running, terminal_cost=terminal,
        u_lower=-task.control_bound, u_upper=task.control_bound,
        q_lower=lower[:4], q_upper=upper[:4], v_lower=lower[4:], v_upper=upper[4:],
        path=no_slip,
        goals=(EndPosition("x", float(task.x_end[0]), task.goal_tolerance),
               LiftOffs(0, task.lift_offs, task.lift_height), Moves()),
    )
    return robot, ground, problem


def hopper_options(task: HopperTask | str = "short"):
    """The solver settings of a hopper plan, chosen by measurement (benchmarks/hopper_bench.md).

    Scholtes from sigma_0 = 1 finds the hops from the start-everywhere guess (the l1 and
    l_inf penalties settled on a foot that never leaves the ground); the homotopy stops at
    a residual of 1e-4 (5 NLPs): smaller residuals stall near 5e-6 on the persistent-contact
    pieces (the step variable of a gap that stays at zero is not pinned down, see the
    time-freezing notes), so the plan relies on the independent verification for the
    physical checks. IPOPT's monotone barrier update and gamma_h = 0.9 (no zero-length
    elements) cut the iteration counts several-fold against the adaptive defaults when
    every NLP is solved tightly (the bench task's loose stepping stones, below, turn
    that round). The
    problem's gap switching function is scaled (`HopperTask.gap_scale`): with the gap in
    metres the relaxed plans at sigma = 1e-4 began impacts 0.1-0.3 mm above the ground,
    and whether such a plan passed its replay depended on round-off (it failed on another
    machine).

    The long task (two hops in 2 s) needs 4 finite elements per interval: with 3 its plans
    ended 6-8e-2 from the exact-impact replay (tolerance 5e-2); and MUMPS's pivot
    tolerance 1e-4, without which NLP 5 ends in a step-computation error. The bench task
    (nosnoc_py's one-hop example, scripts/bench_hopper.py) stops at the residual where
    nosnoc_py's six homotopy steps end, 1e-3: its NLP at sigma = 1e-4 does not converge
    within 1000 iterations, and the plan at 1e-3 passes the verification. It starts at
    sigma_0 = 0.1 (3 NLPs; verified under every perturbation tried, 564-1261 iterations
    against 1088-1174 from sigma_0 = 1); the short task's plans from sigma_0 = 0.1 fail
    their verification, so it keeps sigma_0 = 1.

    The bench task solves the homotopy's stepping stones (the NLPs above its final sigma)
    only to IPOPT tolerances of 0.1 (`Ipopt.intermediate_tol`), the final NLP to 1e-8,
    with IPOPT's adaptive barrier update: each next NLP then starts inside the interior.
    From seven starts moved by round-off the homotopy took 165-221 IPOPT iterations
    (against 561-783 with every NLP at 1e-8 and the monotone barrier), every plan verified,
    costs 21.8-23.5 (22.2). With the monotone barrier the loose stones took 199-253
    iterations (cost 24.2); the adaptive barrier with tight stones had failed (NLPs at the
    cap). The short task's plans with loose stones (monotone or adaptive, 0.1 or 1e-2: 202-678
    iterations against 856-1896, all verified, similar costs) mostly ended in a second
    hop, the foot 4-8 mm up at T, where the tight homotopy's plans land by T; the long
    task's failed (final NLP at the cap, or a plan that fails its replay). Both keep every
    NLP at 1e-8 with the monotone barrier.

    The short and long tasks cut a homotopy step whose NLP fails (`Homotopy.max_refinements`,
    up to 3): on an AVX-512 EPYC the long task's NLP at sigma = 1e-4 ended
    `Restoration_Failed` and the next one at the iteration cap (nlp_failed, 3112
    iterations); solved again from the NLP at 1e-3 through sigma = 3.2e-4, it converged
    (2556 iterations) to a plan 1.1e-2 from its exact-impact replay. A refinement only
    acts on a failed NLP: plans that converge without one are unchanged.

    Every task differentiates the FESD element once (`Ipopt.element_derivatives`, the
    element derivatives on two threads): the bench NLP builds in 0.8 s instead of 2.3 s
    and an iteration takes 19 ms instead of 21. The iterates change by round-off: from
    the seven moved starts above, 153-391 iterations (209 unmoved), every plan verified.

    The short task allows 3 attempts (`ContactSolverOptions.attempts`): which local
    solution the homotopy reaches depends on round-off, and of its plans from starts
    moved by 1e-9 m one in ten failed its replay (deviation 5.2e-2 against the tolerance
    5e-2); a restart from a perturbed guess passed. The long task's plans from moved
    starts fail their open-loop replay (local defects of a few 1e-3 amplified 100-fold
    over five or six impacts); four of five pass the verification as open-loop unstable
    plans, on their local defects. Restarts did not rescue the fifth (two restarts
    failed), so the long task keeps one attempt; so does the bench task, so that its
    times compare single solves.
    """
    import dataclasses

    from tfcontact.task.presets import default_preset, fast_preset

    name = task.name if isinstance(task, HopperTask) else task
    if name == "bench":
        return fast_preset()
    options = default_preset()
    if name == "long":
        return dataclasses.replace(
            options, n_finite_elements=4, attempts=1,
            nlp=dataclasses.replace(options.nlp, options={**options.nlp.options,
                                                          "mumps_pivtol": 1e-4}))
    return options
