"""From a `Task` to what `solve_contact` solves: robot, CLS, time-freezing system,
`ContactProblem` (tracking costs, bounds, path constraints: no-slip, reach, bodies kept
off the terrain, ties; goals) and options.

A terrain of primitives is modelled where the contacts can be: `task_region` gives the
box of the contact centres (the task's own `[terrain] region`, or the base's range
widened by each contact's reach), and the contacts' gaps see only
`Terrain.relevant_to(region, margin=largest contact radius)`. A contact without its own
friction takes the friction of those surfaces.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from scipy.interpolate import CubicSpline

from tfcontact.errors import IncompatibleOptions, InvalidInput
from tfcontact.ocp.stances import Stance
from tfcontact.robot.terrain import Region, Terrain
from tfcontact.task.spec import ApartEntry, PlaneTerrain, Task

UNBOUNDED = 1e20  # IPOPT's infinity: a URDF's 1.8e308 "no limit" means none
RESTING_GAP = 1e-3  # [m] the largest end gap of a contact that `goals.end_height` rests


@dataclass(frozen=True)
class TaskSetup:
    """A built task: the loaded robot, the `ContactProblem`, the solver options, the
    scene description stored in the trajectory's sidecar, and the terrain the contacts'
    gaps model (a `tfcontact.robot.Ground` or the relevant part of a `Terrain`)."""

    task: Task
    robot: Any
    problem: Any
    options: Any
    scene: dict
    terrain: Any = None


def coordinate_names(robot: Any) -> tuple[list[str], list[str]]:
    """(names, units) of the robot's coordinates: the base's `BASE_COORDINATES`, then each
    joint by name (multi-DoF joints other than the base: name_0, name_1, ...)."""
    from tfcontact.robot import BASE_COORDINATES

    model = robot.model
    names, units = [], []
    for i in range(1, model.njoints):
        joint, name = model.joints[i], model.names[i]
        if name == "root_joint":
            names += [n for n, _ in BASE_COORDINATES[robot.spec.base]]
            units += [u for _, u in BASE_COORDINATES[robot.spec.base]]
        elif joint.nv == 1:
            names.append(name)
            units.append("m" if "Prismatic" in joint.shortname() else "rad")
        else:
            names += [f"{name}_{k}" for k in range(joint.nv)]
            units += ["-"] * joint.nv
    return names, units


def build_task(task: Task) -> TaskSetup:
    """Load the task's robot and state its contact problem (module docstring).

    Raises:
        InvalidInput: a field naming a coordinate, joint or frame the robot has not, a
            start with a contact below the terrain, an actuated joint without an effort
            limit (neither in the URDF nor in `effort`), a contact without friction of
            its own that can reach surfaces of different friction.
        RobotLoadError, InvalidRobotModel, FrameNotFound: from `load_robot`.
    """
    from tfcontact.ocp import Constraint
    from tfcontact.ocp.contact import ContactProblem, Periodicity
    from tfcontact.robot import BASE_COORDINATES, ContactSpec, Ground, load_robot
    from tfcontact.task.spec import FRICTION_MODELS
    from tfcontact.timefreezing import Inelastic, time_freeze
    from tfcontact.timefreezing.from_robot import from_robot

    robot = load_robot(task.robot.source, base=task.robot.base,
                       locked_joints=tuple(task.robot.locked),
                       locked_positions=tuple(task.robot.locked.values()),
                       contacts=tuple(ContactSpec(c.frame, c.radius) for c in task.contacts))
    names, _ = coordinate_names(robot)
    joints = [n for n in robot.model.names[1:] if n != "root_joint"]
    base = [n for n, _ in BASE_COORDINATES[robot.spec.base]]
    actuated = list(joints if task.actuated is None else task.actuated)
    unknown = [a for a in actuated if a not in joints and a not in base]
    if unknown:
        raise InvalidInput(f"`actuated` names {unknown}, which are neither joints nor base "
                           f"coordinates of the model; its joints: {joints}, its base: {base}")
    if isinstance(task.terrain, PlaneTerrain):
        ground = Ground(height=task.terrain.height, normal=task.terrain.normal)
        frictions = [0.0 if c.friction is None else c.friction for c in task.contacts]
    else:
        ground = task.terrain.terrain.relevant_to(
            task_region(task, robot),
            margin=max(e.radius for e in (*task.contacts, *task.bodies)))
        frictions = [_terrain_friction(ground, c.frame) if c.friction is None
                     else c.friction for c in task.contacts]
    # unactuated (f_v = -h): the controls, on joints or base coordinates, are added below
    plain = from_robot(robot, ground, mu=frictions, a_n=task.a_n, actuated=[])
    contacts = tuple(dataclasses.replace(c, restitution=entry.restitution, eps_t=entry.eps_t)
                     for c, entry in zip(plain.contacts, task.contacts, strict=True))
    u, forces = _actuation(robot, plain.forces, names, actuated)
    cls = dataclasses.replace(
        plain, u=u, forces=forces, contacts=contacts, q_names=tuple(names), _functions={},
        v_names=tuple(f"v_{n}" for n in names),
        control_names=tuple(f"u_{names[_v_index(robot, a, names)]}" for a in actuated))
    elastic = any(c.restitution > 0 for c in task.contacts)
    friction = FRICTION_MODELS[task.friction_model]()
    tf = time_freeze(cls, method=None if elastic else Inelastic(gap_scale=task.gap_scale,
                                                                friction=friction))

    state_names = list(cls.q_names) + list(cls.v_names)
    _check_names(task, state_names, [c.frame for c in task.contacts])
    x0 = _start(task, names)
    gaps = np.asarray(cls.function("gaps")(x0[:len(names)])).ravel()
    if np.any(gaps < -1e-9):
        below = [c.frame for c, g in zip(task.contacts, gaps, strict=True) if g < -1e-9]
        raise InvalidInput(f"the start puts contacts {below} below the terrain (gaps "
                           f"{gaps.round(4).tolist()} m); raise the base in `start`")

    y, u = tf.y, tf.u
    x = ca.vertcat(y[tf.q_index], y[tf.v_index])
    clock = y[tf.clock_index]
    samples = np.linspace(0.0, task.horizon, task.n_intervals + 1)
    running = task.costs.control * ca.sumsqr(u)
    for name, weight in task.costs.tracking.items():
        i = state_names.index(name)
        reference = _reference(task, name, float(x0[i]), samples)
        running += weight * (x[i] - ca.pw_lin(clock, ca.DM(samples), ca.DM(reference))) ** 2
    terminal = ca.SX(0)
    for name, weight in task.costs.terminal.items():
        i = state_names.index(name)
        terminal += weight * (x[i] - _final_value(task, name, float(x0[i]))) ** 2

    lower, upper = _state_bounds(task, robot, state_names)
    u_bound = _effort(task, robot, actuated)
    # The path rows in `path_row_layout`'s order, which also says which stage keeps each.
    gap = {c.frame: contact.gap for contact, c in zip(cls.contacts, task.contacts, strict=True)}
    entries = {c.frame: c for c in task.contacts}
    for c, entry in zip(cls.contacts, task.contacts, strict=True):
        for name, asked in (("no_slip", entry.no_slip), ("clearance", entry.clearance)):
            if asked and c.mu == 0.0:
                raise InvalidInput(f"`contacts[{entry.frame}].{name}` needs friction > 0 "
                                   "(a frictionless contact has no tangents: no force to "
                                   "stop a slide, no speed along the ground)")
    speed2 = {c.frame: ca.sumsqr(ca.mtimes(contact.tangents.T, cls.v))  # ||v_t||^2
              for contact, c in zip(cls.contacts, task.contacts, strict=True)
              if c.no_slip or c.clearance is not None}
    base = "root_joint" if robot.model.existFrame("root_joint") else "universe"
    to_base = robot.twin.frame_rotation(base).T
    body_gaps = dict(zip((b.frame for b in task.bodies), _body_gaps(task, robot, ground),
                         strict=True))
    separations = {a.name: apart_distance(robot, a) for a in task.apart}
    path = None
    rows, row_upper, row_lower = [], [], []
    for row in path_row_layout(task):
        if row.kind == "no_slip":
            entry = entries[row.name]
            rows.append(speed2[row.name] - entry.no_slip_gain * gap[row.name])
            low, high = -np.inf, 0.0
        elif row.kind == "clearance":  # h v_t^2 <= gap (v_t^2 + c^2), smooth at v_t = 0
            entry = entries[row.name]
            rows.append(entry.clearance * speed2[row.name]
                        - gap[row.name] * (speed2[row.name] + entry.clearance_speed ** 2))
            low, high = -np.inf, 0.0
        elif row.kind == "reach":  # the foot's offset from the base, in the base's axes
            offset = ca.mtimes(to_base, robot.twin.frame_position(row.name)
                               - robot.twin.frame_position(base))
            rows.append(offset["xyz".index(row.axis)])
            low, high = entries[row.name].reach[row.axis]
        elif row.kind in ("body", "apart"):  # rows >= 0 that the start must meet already
            kept = (body_gaps if row.kind == "body" else separations)[row.name]
            short = -float(ca.Function("row", [cls.q], [kept])(x0[:len(names)]))
            if short > 1e-9:
                raise InvalidInput(
                    f"the start puts `bodies[{row.name}]` {short:.4g} m into the terrain; "
                    "raise the base in `start` or shrink its radius" if row.kind == "body"
                    else f"the start puts `apart[{row.name}]`'s frames {short:.4g} m closer "
                    "than its distance; change the start's joints or lower the distance")
            rows.append(kept)
            low, high = 0.0, np.inf
        else:  # a tie: its position (axis "q") and velocity (axis "v") rows
            other = task.ties[row.name]
            sign = -1.0 if other.startswith("-") else 1.0
            i, j = names.index(row.name), names.index(other.removeprefix("-"))
            n = len(names)
            if max(abs(x0[i] - sign * x0[j]), abs(x0[n + i] - sign * x0[n + j])) > 1e-9:
                raise InvalidInput(f"the start breaks `ties.{row.name} = {other!r}` "
                                   f"({row.name} = {x0[i]:g}, {other.removeprefix('-')} = "
                                   f"{x0[j]:g}, velocities {x0[n + i]:g}, {x0[n + j]:g}); "
                                   "start them tied")
            coordinates = cls.q if row.axis == "q" else cls.v
            rows.append(coordinates[i] - sign * coordinates[j])
            low, high = 0.0, 0.0
        row_lower.append(low)
        row_upper.append(high)
    if rows:
        path = Constraint(ca.vertcat(*rows),
                          lower=np.array(row_lower), upper=np.array(row_upper))
    # A contact asked to end resting on a surface ends touching the terrain: without it
    # the plan may meet its end pose in flight above the surface. Half the goal's
    # threshold, so that IPOPT's tolerance cannot leave the plan just outside it.
    frames = [c.frame for c in task.contacts]
    resting = [cls.contacts[frames.index(f)].gap for f in task.goals.end_height]
    end_rows, lower_end, upper_end = [], [], []
    if resting:
        end_rows.append(ca.substitute(ca.vertcat(*resting), cls.q, y[tf.q_index]))
        lower_end += [0.0] * len(resting)
        upper_end += [0.5 * RESTING_GAP] * len(resting)
    periodicity = None
    if task.period is not None:  # the states repeat within the horizon
        periodicity = Periodicity(tuple(state_names.index(n) for n in task.periodic),
                                  _interval_count(task, task.period, "period"),
                                  _interval_count(task, task.period_from, "period_from"))
    else:  # a gait's period: the state ends where it started
        for name in task.periodic:
            i = state_names.index(name)
            end_rows.append(x[i] - float(x0[i]))
            lower_end.append(0.0)
            upper_end.append(0.0)
    end_constraint = None if not end_rows else Constraint(
        ca.vertcat(*end_rows), lower=np.array(lower_end), upper=np.array(upper_end))
    guess = None
    if task.guess == "reference":
        guess = np.column_stack([
            _reference(task, name, float(x0[i]), samples)
            for i, name in enumerate(state_names)])
    problem = ContactProblem(
        system=tf, q0=x0[:len(names)], v0=x0[len(names):], horizon=task.horizon,
        n_intervals=task.n_intervals, running_cost=running, terminal_cost=terminal,
        u_lower=-u_bound, u_upper=u_bound,
        q_lower=lower[:len(names)], q_upper=upper[:len(names)],
        v_lower=lower[len(names):], v_upper=upper[len(names):],
        path=path, terminal=end_constraint, goals=_goals(task, robot, cls), guess=guess,
        periodicity=periodicity)
    scene = {"terrain": task.terrain.to_dict()}
    return TaskSetup(task, robot, problem, solver_options(task), scene, ground)


def solver_options(task: Task) -> Any:
    """The discovery's `ContactSolverOptions`: the task's preset with the task's own
    residual, stop residual, finite elements, discretisation, barrier, BLAS threads and
    attempts (no robot is loaded). A stance
    re-solve that follows a discovery stopped short (`[resolve] discovery_residual`) also
    stops it: its homotopy ends at a failed NLP once its last solved one is within that
    residual (`Homotopy.accept_residual`), the iterate the re-solve reads its stances from.
    Measured on biped-walk's perturbed starts (benchmarks/legged.md): the NLPs after the
    first failure all failed, 3000 of start 002's 4574 discovery iterations."""
    from tfcontact.task.presets import SOLVER_PRESETS

    options = SOLVER_PRESETS[task.solver]()
    if task.complementarity_tolerance is not None:
        options = dataclasses.replace(options, homotopy=dataclasses.replace(
            options.homotopy, tolerance=task.complementarity_tolerance))
    accept = task.resolve.get("discovery_residual") if task.exact_resolve else None
    if accept is not None:
        options = dataclasses.replace(options, homotopy=dataclasses.replace(
            options.homotopy, accept_residual=accept))
    if task.stop_residual is not None:
        options = dataclasses.replace(options, homotopy=dataclasses.replace(
            options.homotopy, stop_residual=task.stop_residual))
    if task.finite_elements is not None:
        options = dataclasses.replace(options, n_finite_elements=task.finite_elements)
    if task.discretization == "standard":
        from tfcontact.fesd import Standard

        options = dataclasses.replace(options, method=Standard())
    if task.barrier is not None:
        options = dataclasses.replace(options, nlp=dataclasses.replace(
            options.nlp, options={**options.nlp.options, "mu_strategy": task.barrier}))
    if task.blas_threads is not None:
        options = dataclasses.replace(options, nlp=dataclasses.replace(
            options.nlp, blas_threads=task.blas_threads))
    if task.attempts is not None:
        options = dataclasses.replace(options, attempts=task.attempts)
    return options


@dataclass(frozen=True)
class PathRow:
    """One row of a built task's path constraint (`path_row_layout`).

    kind: "no_slip", "clearance" (a contact's rows that steer the discovery), "reach" (a
    foot's range along a base axis), "body" (a body kept off the terrain), "apart" (two
    points kept apart) or "tie" (two coordinates moving together); name: the contact's or
    body's frame, the pair's "a-b", or the tie's coordinate; axis: the reach row's base
    axis, or a tie's "q" or "v" row; discovery, resolve: whether the discovery and the
    stance re-solve keep it."""

    kind: str
    name: str
    axis: str = ""
    discovery: bool = True
    resolve: bool = False


def path_row_layout(task: Task) -> tuple[PathRow, ...]:
    """The rows of `build_task(task).problem.path` in order, from the task alone (no robot
    is loaded): each contact's no-slip and clearance rows, then every contact's reach rows,
    the bodies, the pairs kept apart, the ties. The stance re-solve keeps the reach, body
    and apart rows (every closed contact sticks there and the stances found are kept; the
    rest steer the discovery); the discovery drops those with `discovery = false`."""
    rows: list[PathRow] = []
    for c in task.contacts:
        if c.no_slip:
            rows.append(PathRow("no_slip", c.frame))
        if c.clearance is not None:
            rows.append(PathRow("clearance", c.frame))
    for c in task.contacts:
        rows += [PathRow("reach", c.frame, axis, resolve=True) for axis in c.reach]
    rows += [PathRow("body", b.frame, discovery=b.discovery, resolve=True)
             for b in task.bodies]
    rows += [PathRow("apart", a.name, discovery=a.discovery, resolve=True)
             for a in task.apart]
    for name in task.ties:
        rows += [PathRow("tie", name, "q"), PathRow("tie", name, "v")]
    return tuple(rows)


def resolve_path_rows(task: Task) -> tuple[int, ...]:
    """The rows of `build_task(task).problem.path` that a stance re-solve keeps
    (`StanceResolve.path_rows`): the contacts' reach rows, a leg's range of motion, and
    the rows keeping `bodies` off the terrain (`path_row_layout`)."""
    return tuple(k for k, row in enumerate(path_row_layout(task)) if row.resolve)


def discovery_path_rows(task: Task) -> tuple[int, ...] | None:
    """The rows of `build_task(task).problem.path` that the discovery keeps (`Discover`'s
    `path_rows`): all but those of the `bodies` kept by the stance re-solve only
    (`BodyEntry.discovery = false`); None when it keeps all."""
    layout = path_row_layout(task)
    if all(row.discovery for row in layout):
        return None
    return tuple(k for k, row in enumerate(layout) if row.discovery)


def _body_gaps(task: Task, robot: Any, ground: Any) -> list[Any]:
    """g(q) [m] of each of `task.bodies` against the terrain the contacts see (`ground`: a
    `Ground` half-space or a `Terrain`, each with the contacts' `gap`), in the robot
    twin's q."""
    return [ground.gap(_frame_position(robot, body.frame, f"`bodies[{body.frame}].frame`"),
                       body.radius) for body in task.bodies]


def apart_distance(robot: Any, pair: ApartEntry) -> ca.SX:
    """|p_a - p_b| - distance [m] of an `ApartEntry` in the robot twin's q (>= 0: the
    frames' origins are far enough apart). The norm is smoothed by 1e-12 m^2 under the
    root so that its derivatives stay finite where the points would meet."""
    a, b = (_frame_position(robot, f, f"`apart[{pair.name}].frames`' {f!r}")
            for f in pair.frames)
    return ca.sqrt(ca.sumsqr(a - b) + 1e-12) - pair.distance


def _frame_position(robot: Any, frame: str, where: str) -> ca.SX:
    """The twin's position of `frame` in q, or InvalidInput naming `where` and the
    model's frames."""
    if frame not in robot.twin.frame_names:
        raise InvalidInput(f"{where} is not a frame of the model; its frames: "
                           f"{', '.join(robot.twin.frame_names)}")
    return robot.twin.frame_position(frame)


def task_stances(task: Task) -> tuple[Stance, ...]:
    """The task's given contact sequence (`Task.stances`) as `tfcontact.ocp.stances.Stance`s:
    its contacts by index in `task.contacts`, each stance until the next one's start or
    the horizon (empty: none given)."""
    frames = [c.frame for c in task.contacts]
    ends = [s.start for s in task.stances[1:]] + [task.horizon]
    return tuple(Stance(tuple(sorted(frames.index(f) for f in s.closed)), s.start, end)
                 for s, end in zip(task.stances, ends, strict=True))


def contact_reach(robot: Any, frame: str) -> float:
    """An upper bound of the distance from the base to the centre of the contact on
    `frame` [m]: the lengths of the joint offsets along the chain from the base (the
    floating/planar root joint, or the world for a fixed base) to the frame, plus each
    prismatic joint's largest |position|. Revolute joints only turn the offsets.
    Infinite for a prismatic joint without limits."""
    model = robot.model
    f = model.frames[model.getFrameId(frame)]
    reach = float(np.linalg.norm(f.placement.translation))
    j = f.parentJoint
    while j > 0 and model.names[j] != "root_joint":
        joint = model.joints[j]
        reach += float(np.linalg.norm(model.jointPlacements[j].translation))
        if "Prismatic" in joint.shortname():
            i = joint.idx_q
            stroke = max(abs(float(model.lowerPositionLimit[i])),
                         abs(float(model.upperPositionLimit[i])))
            reach += stroke if stroke < UNBOUNDED else math.inf
        j = model.parents[j]
    return reach


def task_region(task: Task, robot: Any) -> Region:
    """The box where the task's contact centres stay [m]: `task.terrain.region` if given;
    else the base's range widened on every side by the largest `contact_reach`.

    The base's range along x, y, z: its `bounds` where both are finite (hard limits of
    the plan), else the span of its start, way points and `goals.end` values (the plan
    is pulled along them; it may leave that span by less than a leg's reach, which the
    widening covers). A base axis the model has not (a planar base's y) stays at 0; a
    fixed base sits at the origin. Below the base nothing is cut (z from -inf): every
    surface under the robot stays.
    """
    if not isinstance(task.terrain, PlaneTerrain) and task.terrain.region is not None:
        return task.terrain.region
    from tfcontact.robot import BASE_COORDINATES

    reach = max(contact_reach(robot, c.frame) for c in task.contacts)
    base = [n for n, _ in BASE_COORDINATES.get(robot.spec.base, ())]
    lower, upper = [], []
    for axis in ("x", "y", "z"):
        if axis in task.bounds and all(abs(b) < UNBOUNDED for b in task.bounds[axis]):
            low, high = task.bounds[axis]
        elif axis in base:
            values = [task.start.get(axis, 0.0)]
            values += [w.values[axis] for w in task.waypoints if axis in w.values]
            values += [task.goals.end[axis]] if axis in task.goals.end else []
            low, high = min(values), max(values)
        else:
            low = high = 0.0
        lower.append(low - reach)
        upper.append(high + reach)
    lower[2] = -math.inf
    return Region(tuple(lower), tuple(upper))


def _terrain_friction(terrain: Terrain, frame: str) -> float:
    try:
        return terrain.friction
    except IncompatibleOptions:
        values = sorted({p.friction for p in terrain.primitives})
        raise InvalidInput(
            f"`contacts[{frame}].friction` is omitted, but the surfaces it can reach have "
            f"different friction coefficients {values}; give the contact its own friction, "
            "or a `[terrain] region` that keeps only surfaces of one friction") from None


def _v_index(robot: Any, name: str, names: list[str]) -> int:
    """The velocity index of a joint or base coordinate `name` (`names`: the
    coordinates' names, the base's first)."""
    if robot.model.existJointName(name):
        return robot.model.joints[robot.model.getJointId(name)].idx_v
    return names.index(name)


def _actuation(robot: Any, unforced: ca.SX, names: list[str], actuated: list[str]
               ) -> tuple[ca.SX, ca.SX]:
    """(u, f_v = S u - h) from `unforced` = -h, one control per `actuated` name, in order:
    a joint's force or a generalised force on a base coordinate (the idealised actuator of
    TF-8's hopper, whose hip torque turns the leg angle directly)."""
    u = ca.SX.sym("u", len(actuated))
    selection = np.zeros((len(names), len(actuated)))
    for k, a in enumerate(actuated):
        selection[_v_index(robot, a, names), k] = 1.0
    return u, unforced + ca.mtimes(ca.DM(selection), u)


def _check_names(task: Task, state_names: list[str], frames: list[str]) -> None:
    coordinates = state_names[:len(state_names) // 2]
    # fields that may name velocities too, and those about coordinates only
    fields = [("start", task.start, state_names), ("bounds", task.bounds, state_names),
              ("start_ranges", task.start_ranges, state_names),
              ("costs.tracking", task.costs.tracking, state_names),
              ("costs.terminal", task.costs.terminal, state_names),
              *((f"waypoints[t={w.time:g}]", w.values, state_names) for w in task.waypoints),
              ("goals.end", task.goals.end, coordinates),
              ("goals.progress", task.goals.progress, coordinates),
              ("goals.lift_offs", task.goals.lift_offs, frames),
              ("goals.end_height", task.goals.end_height, frames),
              ("periodic", dict.fromkeys(task.periodic), state_names),
              ("ties", {**task.ties, **{v.removeprefix("-"): v for v in task.ties.values()}},
               coordinates)]
    for where, mapping, allowed in fields:
        unknown = [k for k in mapping if k not in allowed]
        if unknown:
            kind = "contacts" if allowed is frames else "names"
            raise InvalidInput(f"`{where}` names {unknown}, which the robot has not; its "
                               f"{kind}: {', '.join(allowed)}")


def _interval_count(task: Task, duration: float, where: str) -> int:
    """`duration` [s] in control intervals of the task; refused unless a multiple."""
    step = task.horizon / task.n_intervals
    k = round(duration / step)
    if abs(k * step - duration) > 1e-9 * task.horizon:
        raise InvalidInput(f"`{where}` = {duration:g} s must be a multiple of the control "
                           f"interval T / N = {step:g} s")
    return k


def _start(task: Task, names: list[str]) -> np.ndarray:
    x0 = np.zeros(2 * len(names))
    state_names = names + [f"v_{n}" for n in names]
    for name, value in task.start.items():
        x0[state_names.index(name)] = value
    return x0


def _reference(task: Task, name: str, start: float, samples: np.ndarray) -> np.ndarray:
    """The reference of `name` at `samples`: a cubic spline from its start value through
    the way points naming it, held after the last (the start held without any)."""
    knots = [0.0] + [w.time for w in task.waypoints if name in w.values]
    values = [start] + [w.values[name] for w in task.waypoints if name in w.values]
    if len(knots) == 1:
        return np.full(samples.shape, start)
    spline = CubicSpline(knots, values) if len(knots) > 2 else None
    held = np.clip(samples, 0.0, knots[-1])
    return spline(held) if spline is not None else np.interp(held, knots, values)


def _final_value(task: Task, name: str, start: float) -> float:
    if name in task.goals.end:
        return task.goals.end[name]
    named = [w.values[name] for w in task.waypoints if name in w.values]
    return named[-1] if named else start


def _state_bounds(task: Task, robot: Any, state_names: list[str]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The URDF's joint position limits (none for the base), replaced by `task.bounds`."""
    n = len(state_names) // 2
    lower, upper = np.full(2 * n, -UNBOUNDED), np.full(2 * n, UNBOUNDED)
    model = robot.model
    base_dofs = 0
    if model.existJointName("root_joint"):
        base_dofs = model.joints[model.getJointId("root_joint")].nv
    limits_low = np.asarray(model.lowerPositionLimit, dtype=float)
    limits_high = np.asarray(model.upperPositionLimit, dtype=float)
    for i in range(base_dofs, n):
        if abs(limits_low[i]) < UNBOUNDED:
            lower[i] = limits_low[i]
        if abs(limits_high[i]) < UNBOUNDED:
            upper[i] = limits_high[i]
    for name, (low, high) in task.bounds.items():
        i = state_names.index(name)
        lower[i], upper[i] = low, high
    return lower, upper


def _effort(task: Task, robot: Any, actuated: list[str]) -> np.ndarray:
    bounds = []
    for joint in actuated:
        if joint in task.effort:
            bounds.append(task.effort[joint])
            continue
        if not robot.model.existJointName(joint):
            raise InvalidInput(f"the base coordinate `{joint}` is actuated but has no effort "
                               f"limit (a URDF gives none for the base); give one in the "
                               f"task: effort = {{ {joint} = 50.0 }}")
        limit = float(robot.model.effortLimit[_v_index(robot, joint, [])])
        if not (0.0 < limit < UNBOUNDED):
            raise InvalidInput(f"joint `{joint}` has no effort limit in the URDF; give one "
                               f"in the task: effort = {{ {joint} = 50.0 }}")
        bounds.append(limit)
    unknown = [k for k in task.effort if k not in actuated]
    if unknown:
        raise InvalidInput(f"`effort` names {unknown}, which are not actuated; actuated: "
                           f"{actuated}")
    return np.asarray(bounds)


def _goals(task: Task, robot: Any, cls: Any) -> tuple:
    from tfcontact.ocp.goals import EndHeight, EndPosition, Flight, LiftOffs, Moves, Progress

    goals: list = [EndPosition(k, v, task.goals.tolerance) for k, v in task.goals.end.items()]
    goals += [Progress(k, v) for k, v in task.goals.progress.items()]
    frames = [c.frame for c in task.contacts]
    goals += [LiftOffs(frames.index(k), n, task.goals.lift_height)
              for k, n in task.goals.lift_offs.items()]
    for frame, height in task.goals.end_height.items():
        contact = task.contacts[frames.index(frame)]
        lowest = ca.Function(f"z_low_{frame}", [cls.q],
                             [robot.twin.frame_position(frame)[2] - contact.radius])
        goals.append(EndHeight(frames.index(frame), height, task.goals.height_tolerance,
                               lowest, touch=RESTING_GAP))
    if task.goals.flight is not None:
        goals.append(Flight(tuple(range(len(frames))), task.goals.flight,
                            task.goals.flight_height))
    if task.goals.moves:
        goals.append(Moves())
    return tuple(goals)
