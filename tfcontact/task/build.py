"""From a `Task` to what `solve_contact` solves: robot, CLS, time-freezing system,
`ContactProblem` (tracking costs, bounds, no-slip path constraints, goals) and options."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from scipy.interpolate import CubicSpline

from tfcontact.errors import InvalidInput
from tfcontact.task.spec import Task

UNBOUNDED = 1e20  # IPOPT's infinity: a URDF's 1.8e308 "no limit" means none


@dataclass(frozen=True)
class TaskSetup:
    """A built task: the loaded robot, the `ContactProblem`, the solver options and the
    scene description stored in the trajectory's sidecar."""

    task: Task
    robot: Any
    problem: Any
    options: Any
    scene: dict


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
            limit (neither in the URDF nor in `effort`).
        RobotLoadError, InvalidRobotModel, FrameNotFound: from `load_robot`.
    """
    from tfcontact.ocp import Constraint
    from tfcontact.ocp.contact import ContactProblem
    from tfcontact.robot import ContactSpec, Ground, load_robot
    from tfcontact.task.presets import SOLVER_PRESETS
    from tfcontact.timefreezing import Inelastic, time_freeze
    from tfcontact.timefreezing.from_robot import from_robot

    robot = load_robot(task.robot.source, base=task.robot.base,
                       locked_joints=tuple(task.robot.locked),
                       locked_positions=tuple(task.robot.locked.values()),
                       contacts=tuple(ContactSpec(c.frame, c.radius) for c in task.contacts))
    names, _ = coordinate_names(robot)
    joints = [n for n in robot.model.names[1:] if n != "root_joint"]
    actuated = list(joints if task.actuated is None else task.actuated)
    unknown = [a for a in actuated if a not in joints]
    if unknown:
        raise InvalidInput(f"`actuated` names {unknown}, which are not joints of the model; "
                           f"its joints: {joints}")
    ground = Ground(height=task.terrain.height, normal=task.terrain.normal)
    frictional = any(c.friction > 0 for c in task.contacts)
    plain = from_robot(robot, ground, mu=1.0 if frictional else 0.0, a_n=task.a_n,
                       actuated=actuated)
    # from_robot gives every contact the same mu; each contact takes its own here.
    contacts = tuple(
        dataclasses.replace(c, mu=entry.friction, restitution=entry.restitution,
                            tangents=c.tangents if entry.friction > 0 else None)
        for c, entry in zip(plain.contacts, task.contacts, strict=True))
    cls = dataclasses.replace(
        plain, contacts=contacts, q_names=tuple(names),
        v_names=tuple(f"v_{n}" for n in names),
        control_names=tuple(f"u_{names[_v_index(robot, a)]}" for a in actuated))
    elastic = any(c.restitution > 0 for c in task.contacts)
    tf = time_freeze(cls, method=None if elastic else Inelastic(gap_scale=task.gap_scale))

    state_names = list(cls.q_names) + list(cls.v_names)
    _check_names(task, state_names, [c.frame for c in task.contacts])
    x0 = _start(task, robot, names)
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
    path = None
    rows = []
    for c, entry in zip(cls.contacts, task.contacts, strict=True):
        if entry.no_slip:
            if entry.friction == 0.0:
                raise InvalidInput(f"`contacts[{entry.frame}].no_slip` needs friction > 0 "
                                   "(a frictionless contact has no tangential force to stop "
                                   "a slide)")
            slip = ca.mtimes(c.tangents.T, cls.v)
            rows.append(ca.sumsqr(slip) - entry.no_slip_gain * c.gap)
    if rows:
        path = Constraint(ca.vertcat(*rows), upper=0.0)
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
        path=path, goals=_goals(task), guess=guess)
    options = SOLVER_PRESETS[task.solver]()
    scene = {"terrain": task.terrain.to_dict()}
    return TaskSetup(task, robot, problem, options, scene)


def _v_index(robot: Any, joint: str) -> int:
    return robot.model.joints[robot.model.getJointId(joint)].idx_v


def _check_names(task: Task, state_names: list[str], frames: list[str]) -> None:
    fields = {"start": task.start, "bounds": task.bounds,
              "costs.tracking": task.costs.tracking, "costs.terminal": task.costs.terminal,
              "goals.end": task.goals.end, "goals.progress": task.goals.progress}
    fields.update({f"waypoints[t={w.time:g}]": w.values for w in task.waypoints})
    for where, mapping in fields.items():
        allowed = state_names if where in ("start", "bounds", "costs.tracking",
                                           "costs.terminal") or where.startswith("waypoints") \
            else state_names[:len(state_names) // 2]
        unknown = [k for k in mapping if k not in allowed]
        if unknown:
            raise InvalidInput(f"`{where}` names {unknown}, which the robot has not; its "
                               f"names: {', '.join(allowed)}")
    unknown = [k for k in task.goals.lift_offs if k not in frames]
    if unknown:
        raise InvalidInput(f"`goals.lift_offs` names {unknown}, which are not contacts; "
                           f"the contacts: {frames}")


def _start(task: Task, robot: Any, names: list[str]) -> np.ndarray:
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
        limit = float(robot.model.effortLimit[_v_index(robot, joint)])
        if not (0.0 < limit < UNBOUNDED):
            raise InvalidInput(f"joint `{joint}` has no effort limit in the URDF; give one "
                               f"in the task: effort = {{ {joint} = 50.0 }}")
        bounds.append(limit)
    unknown = [k for k in task.effort if k not in actuated]
    if unknown:
        raise InvalidInput(f"`effort` names {unknown}, which are not actuated; actuated: "
                           f"{actuated}")
    return np.asarray(bounds)


def _goals(task: Task) -> tuple:
    from tfcontact.ocp.goals import EndPosition, LiftOffs, Moves, Progress

    goals: list = [EndPosition(k, v, task.goals.tolerance) for k, v in task.goals.end.items()]
    goals += [Progress(k, v) for k, v in task.goals.progress.items()]
    frames = [c.frame for c in task.contacts]
    goals += [LiftOffs(frames.index(k), n, task.goals.lift_height)
              for k, n in task.goals.lift_offs.items()]
    if task.goals.moves:
        goals.append(Moves())
    return tuple(goals)
