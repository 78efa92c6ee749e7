"""A solved contact plan (`tfcontact.ocp.contact.ContactResult`) as a `Trajectory` file.

The samples are the plan's FESD points in numerical time tau: the element boundaries and
the interior stage points, with the clock t(tau), the speed of time s and the controls of
the interval holding each sample. Contact data come from the plan's CLS:

* gap f_c(q) [m] and normal velocity n(q)^T v [m/s] per contact;
* impulse [N s] of each frozen piece (an impact), at the piece's exit sample, from the
  momentum balance M (v+ - v-) = sum_i n_i Lambda_n,i + B_i Lambda_t,i of
  `to_physical_time` ([AUTO23] eq. (19));
* force [N] on every running interval where a contact is closed (gap <= `closed_gap`),
  from the momentum balance in physical time (M dv - int f_v dt) / dt = J^T lambda
  (`tfcontact.verify.contact_impulses`), at the interval's first sample.

Impulses and forces are given in the world frame: Lambda_n n_w + Lambda_t T_w with the
world normal n_w and tangents T_w of each contact (`directions`; default: flat ground,
n_w = z, T_w = x (planar) or (x, y)). Several CLS contacts may belong to one robot contact
(a ball in a box: four walls, one ball): their gap is the smallest, their normal velocity
the one of the nearest wall, their forces and impulses add up (`contact_map`), and the
per-CLS-contact gaps are kept as the extra array `cls_gaps`.

The sidecar's `model` (`describe_robot`) describes the robot without the repository: the
URDF's SHA-256 and where it is, the base, gravity, and the names and units of q, v and u
with the joint each control drives. `check_plan` checks a saved plan's physics from its
recorded data (`tfcontact check FILE`, `scripts/check_trajectory.py`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput, RobotLoadError, TfcontactError
from tfcontact.plan_format.trajectory import Trajectory, physical_time
from tfcontact.robot.spec import BASE_COORDINATES, dof_units

GROUND_NORMAL = (0.0, 0.0, 1.0)


def _jsonable(value: Any) -> Any:
    """Plain JSON types; non-finite floats become None, numpy scalars Python numbers."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return repr(value)


def solver_record(result: Any) -> dict[str, Any]:
    """The `solver` entry of a plan's sidecar: settings, work counters and timings.

    Keys: status, message, objective, cost, nlp_count, iterations (total),
    iterations_per_nlp, complementarity_residual, timings [s] (build, solve, verify,
    total, summed over attempts), settings (discretisation, relaxation, homotopy, IPOPT,
    attempts, horizons, N, speed of time bounds), history (one dict per homotopy step:
    sigma, iterations, objective, residual, seconds, ipopt_status, evaluation_seconds,
    intermediate, refined) and
    attempts (one dict per solve: seed, status, iterations, solve_time, verify_time,
    end_state_deviation, chosen: whether this plan is that solve's).
    """
    ocp = result.ocp
    build = ocp.build
    disc = build.discretization
    problem = result.problem
    mpcc = ocp.mpcc_result
    settings = {
        "scheme": disc.tableau.name,
        "n_intervals": disc.grid.n_intervals,
        "n_finite_elements": disc.grid.n_finite_elements,
        "method": repr(disc.method),
        "relaxation": mpcc.relaxation,
        "horizon": problem.horizon,
        "numerical_horizon": problem.tau_horizon,
        "speed_of_time": list(problem.speed_of_time),
        "stagewise_clock": problem.stagewise_clock,
        "n_variables": build.mpcc.n_w,
        "n_constraints": build.mpcc.n_g,
        "n_complementarities": build.mpcc.n_comp,
    }
    options = getattr(result, "options", None)
    if options is not None:
        settings.update({"homotopy": dataclasses.asdict(options.homotopy),
                         "ipopt": dataclasses.asdict(options.nlp),
                         "relaxation_options": repr(options.relaxation),
                         "attempts": options.attempts,
                         "restart_noise": options.restart_noise})
    return _jsonable({
        "status": result.status,
        "message": result.message,
        "objective": ocp.objective,
        "cost": ocp.cost,
        "nlp_count": ocp.n_nlps,
        "iterations": ocp.total_iterations,
        "iterations_per_nlp": list(ocp.iterations),
        "complementarity_residual": ocp.residual,
        "timings": dict(result.timings),
        "settings": settings,
        "history": [dataclasses.asdict(step) for step in mpcc.history],
        "attempts": _attempts(result),
    })


def _attempts(result: Any) -> list[dict[str, Any]]:
    """One dict per solve, `chosen` marking the one whose plan this is."""
    chosen = getattr(result, "chosen", None)
    return [{**dataclasses.asdict(a), "chosen": k == chosen}
            for k, a in enumerate(getattr(result, "attempts", ()))]


def _samples(ocp: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tau, y, interval index) at the element boundaries and interior stage points."""
    n_fe = ocp.build.discretization.grid.n_finite_elements
    n_el = ocp.h.size
    taus = [ocp.t[:1]]
    ys = [ocp.x[:1]]
    owner = [np.zeros(1, dtype=int)]
    for e in range(n_el):
        inner = ocp.t_stages[e] < ocp.t[e + 1] - 1e-12 * max(1.0, abs(ocp.t[e + 1]))
        inner &= ocp.t_stages[e] > ocp.t[e]
        taus += [ocp.t_stages[e][inner], ocp.t[e + 1 : e + 2]]
        ys += [ocp.x_stages[e][inner], ocp.x[e + 1 : e + 2]]
        owner.append(np.full(int(inner.sum()) + 1, e // n_fe))
    return np.concatenate(taus), np.vstack(ys), np.concatenate(owner)


def ground_directions(scene: dict[str, Any], cls: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per CLS contact, the world normal and tangents of the scene's one ground plane
    (`scene["terrain"]["normal"]`, default z; tangents as `robot.Ground`): the default
    `directions` of the trajectory adapters."""
    from tfcontact.robot import Ground

    ground = Ground(normal=tuple(scene.get("terrain", {}).get("normal", GROUND_NORMAL)))
    return [(np.asarray(ground.normal),
             ground.tangents(c.n_tangents == 1) if c.n_tangents else np.zeros((3, 0)))
            for c in cls.contacts]


def trajectory_from_result(
    result: Any,
    robot_spec: Any,
    scene: dict[str, Any] | None = None,
    *,
    directions: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    contact_map: Sequence[int] | None = None,
    closed_gap: float = 1e-3,
    task: dict[str, Any] | None = None,
) -> Trajectory:
    """The `Trajectory` of a solved contact plan (module docstring).

    Main args:
        result: a `ContactResult` from `tfcontact.ocp.contact.solve_contact`.
        robot_spec: the `tfcontact.robot.RobotSpec` (or its `to_dict()`) that rebuilds the
            robot whose configuration is the plan's q (q in the robot's own coordinates).
        scene: the scene dict (terrain, boxes, holes); default flat ground at height 0.

    Other args:
        directions: per CLS contact, (n_w (3,), T_w (3, n_t)): world normal and tangents
            used to express impulses and forces in the world frame, or a function of q
            returning them (a terrain whose normal changes along it: `terrain_directions`);
            default the ground of `scene["terrain"]` (its "normal", default z; tangents as
            `robot.Ground`).
        contact_map: per CLS contact, the index of the robot contact it belongs to; default
            one to one, or all to the single robot contact.
        closed_gap: a contact is closed, and may carry a force, where its gap <= this [m].
        task: what the plan was asked, stored as the sidecar's `task` (default empty).

    Returns:
        The `Trajectory` (status = `result.status`; solver = `solver_record(result)`;
        verification = `result.verification.to_dict()`; model = `describe_robot`;
        frozen_rate_tol = the time-freezing layer's `FROZEN_RATE_TOL`).

    Raises:
        InvalidInput: the robot's contacts cannot be matched with the CLS's contacts.
    """
    from tfcontact.timefreezing import FROZEN_RATE_TOL
    from tfcontact.verify import contact_impulses

    robot = robot_spec if isinstance(robot_spec, dict) else robot_spec.to_dict()
    scene = {"terrain": {"type": "flat", "height": 0.0}} if scene is None else dict(scene)
    system = result.system
    cls = system.cls
    n_c = cls.n_contacts
    n_robot = len(robot.get("contacts", []))
    if contact_map is None:
        if n_robot == n_c:
            contact_map = list(range(n_c))
        elif n_robot == 1:
            contact_map = [0] * n_c
        else:
            raise InvalidInput(
                f"the robot has {n_robot} contacts and the plan's CLS {n_c}: give "
                "`contact_map` (the robot contact of each CLS contact)")
    contact_map = [int(i) for i in contact_map]
    if len(contact_map) != n_c or any(not 0 <= i < n_robot for i in contact_map):
        raise InvalidInput(
            f"`contact_map` must give one robot contact in [0, {n_robot}) per CLS contact "
            f"({n_c}), got {contact_map}")
    if directions is None:
        directions = ground_directions(scene, cls)
    directions_at = directions if callable(directions) else (lambda _q: directions)

    def checked(entries: Any) -> list[tuple[np.ndarray, np.ndarray]]:
        out = [(np.asarray(n, float).reshape(3), np.asarray(t, float).reshape(3, -1))
               for n, t in entries]
        if len(out) != n_c:
            raise InvalidInput(f"`directions` has {len(out)} entries, expected {n_c}")
        return out

    ocp = result.ocp
    tau, y, interval = _samples(ocp)
    n = tau.size
    q, v = y[:, system.q_index], y[:, system.v_index]
    # the clock at stage points may dip by round-off inside a frozen piece
    clock = np.maximum.accumulate(y[:, system.clock_index])
    u = result.u[interval]
    s = result.speed_of_time[interval]
    gaps_all = np.asarray(cls.function("gaps")(q.T)).T.reshape(n, n_c)
    normals = cls.function("normals")
    vn_all = np.stack([np.asarray(normals(qk)).T @ vk for qk, vk in zip(q, v, strict=True)])
    vn_all = vn_all.reshape(n, n_c)

    sampled = [checked(directions_at(qk)) for qk in q]

    def world(lam_n: float, lam_t: np.ndarray, i: int, k: int) -> np.ndarray:
        """Contact i's impulse or force (lam_n, lam_t) in the world frame at sample k."""
        n_w, t_w = sampled[k][i]
        return lam_n * n_w + (t_w @ lam_t if t_w.shape[1] else 0.0)

    gap = np.zeros((n, n_robot))
    normal_velocity = np.zeros((n, n_robot))
    for r in range(n_robot):
        members = [i for i in range(n_c) if contact_map[i] == r]
        if not members:
            gap[:, r] = np.inf
            continue
        nearest = np.array(members)[np.argmin(gaps_all[:, members], axis=1)]
        gap[:, r] = gaps_all[np.arange(n), nearest]
        normal_velocity[:, r] = vn_all[np.arange(n), nearest]
    gap[~np.isfinite(gap)] = 0.0

    # impulses of the frozen pieces, at their exit samples
    impulse = np.zeros((n, n_robot, 3))
    boundary = np.flatnonzero(np.isin(tau, ocp.t))
    covered = np.zeros(n, dtype=bool)
    for imp in result.physical.impacts:
        k = boundary[imp.index[1]] if imp.index[1] < boundary.size else n - 1
        covered[boundary[min(imp.index[0], boundary.size - 1)]:k + 1] = True
        for i in range(n_c):
            n_t = cls.contacts[i].n_tangents
            impulse[k, contact_map[i]] += world(imp.normal_impulse[i],
                                                imp.tangential_impulse[i, :n_t], i, k)
    # The physical layer sees frozen pieces between element boundaries only; one that
    # starts or ends at a stage point gets its impulse here, from M (v+ - v-) = A Lambda
    # over the contacts closed at its entry (A: their normals and tangents).
    mass = cls.function("mass")
    tangents = [cls.function(f"tangents_{i}") for i in range(n_c)]

    def directions_at(qk: np.ndarray, i: int) -> np.ndarray:
        """Contact i's generalised normal and tangents at qk, as columns."""
        cols = [np.asarray(normals(qk))[:, i:i + 1]]
        if cls.contacts[i].n_tangents:
            cols.append(np.asarray(tangents[i](qk)))
        return np.hstack(cols)

    for entry, exit_ in _frozen_pieces(tau, clock, FROZEN_RATE_TOL):
        if covered[entry:exit_ + 1].all():
            continue
        closed = [i for i in range(n_c) if gaps_all[entry, i] <= closed_gap]
        if not closed:
            continue
        blocks = [(i, directions_at(q[entry], i)) for i in closed]
        lam = np.linalg.lstsq(np.hstack([a for _, a in blocks]),
                              np.asarray(mass(q[entry])) @ (v[exit_] - v[entry]), rcond=None)[0]
        col = 0
        for i, a in blocks:
            impulse[exit_, contact_map[i]] += world(lam[col], lam[col + 1:col + a.shape[1]], i,
                                                    entry)
            col += a.shape[1]

    # forces on running intervals with a closed contact, from the momentum balance
    force = np.zeros((n, n_robot, 3))
    dt = np.diff(clock)
    running = dt > 1e-3 * np.maximum(np.diff(tau), 1e-300)
    forces = cls.function("forces")

    def jac(qk: np.ndarray) -> np.ndarray:
        closed = gaps_of(qk) <= closed_gap
        nrm = np.asarray(normals(qk))
        cols = []
        for i in range(n_c):
            cols.append(nrm[:, i : i + 1] * closed[i])
            if cls.contacts[i].n_tangents:
                cols.append(np.asarray(tangents[i](qk)) * closed[i])
        return np.hstack(cols)

    def gaps_of(qk: np.ndarray) -> np.ndarray:
        return np.asarray(cls.function("gaps")(qk)).ravel()

    for k in np.flatnonzero(running):
        if not np.any(gaps_all[k] <= closed_gap):
            continue
        lam, _ = contact_impulses(
            clock[k : k + 2], q[k : k + 2], v[k : k + 2], u[k : k + 2],
            mass_matrix=lambda qk: np.asarray(mass(qk)),
            smooth_force=lambda qk, vk, uk: np.asarray(forces(qk, vk, uk)).reshape(-1),
            contact_jacobian=jac)
        lam = lam[0] / dt[k]
        col = 0
        for i in range(n_c):
            n_t = cls.contacts[i].n_tangents
            force[k, contact_map[i]] += world(lam[col], lam[col + 1 : col + 1 + n_t], i, k)
            col += 1 + n_t

    verification = result.verification.to_dict()
    return Trajectory(
        tau=tau, clock=clock, s=s, q=q, v=v, u=u, gap=gap, normal_velocity=normal_velocity,
        force=force, impulse=impulse, status=result.status, robot=_jsonable(robot),
        scene=_jsonable(scene), solver=solver_record(result),
        verification=_jsonable(verification),
        extras={"cls_gaps": gaps_all} if n_c != n_robot else {},
        model=describe_robot(robot, cls), task=_jsonable(task or {}),
        frozen_rate_tol=FROZEN_RATE_TOL,
    )


def terrain_directions(robot: Any, terrain: Any) -> Any:
    """q -> [(n_w, T_w) per contact of `robot`]: the world normal and tangents of each
    contact sphere's nearest terrain point (`Robot.contact_terms`), the `directions` of
    `trajectory_from_result` on a `tfcontact.robot.Terrain` (slopes, box edges)."""
    import casadi as ca

    terms = robot.contact_terms(terrain)  # against a Terrain: SX in q
    outputs = [e for t in terms for e in (t.world_normal, t.world_tangents)]
    evaluate = ca.Function("directions", [robot.twin.q], outputs)

    def directions(q: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        values = [np.asarray(x) for x in evaluate(q)]  # two outputs per contact
        return [(values[2 * i].ravel(), values[2 * i + 1]) for i in range(len(terms))]

    return directions


def _frozen_pieces(tau: np.ndarray, clock: np.ndarray,
                   rate_tol: float) -> tuple[tuple[int, int], ...]:
    """(entry, exit) samples of the frozen pieces, as `physical_time` finds them."""
    n = tau.size
    probe = Trajectory(tau=tau, clock=clock, s=np.ones(n), q=np.zeros((n, 0)),
                       v=np.zeros((n, 0)), u=np.zeros((n, 0)), gap=np.zeros((n, 0)),
                       normal_velocity=np.zeros((n, 0)), frozen_rate_tol=rate_tol)
    return physical_time(probe).frozen_index


def plan_summary(result: Any) -> dict[str, Any]:
    """The numbers of a benchmark row: status, objective, NLPs, IPOPT iterations,
    complementarity residual, wall times [s], impact times [s] and the verification."""
    ocp = result.ocp
    return _jsonable({
        "status": result.status,
        "success": result.success,
        "objective": ocp.cost,
        "nlp_count": ocp.n_nlps,
        "iterations": ocp.total_iterations,
        "iterations_per_nlp": list(ocp.iterations),
        "complementarity_residual": ocp.residual,
        "timings": dict(result.timings),
        "impact_times": result.physical.impact_times.tolist(),
        "attempts": _attempts(result),
        "message": result.message,
        "verification": result.verification.to_dict(),
    })


IMPACT_TAU = 1e-3
"""Numerical duration [s] given to a touchdown of a polished plan in its `Trajectory`: the
impact becomes a frozen piece (the clock stands still) as in a time-freezing plan."""


def trajectory_from_polished(
    plan: Any,
    cls: Any,
    robot_spec: Any,
    scene: dict[str, Any] | None = None,
    *,
    solver: dict[str, Any] | None = None,
    task: dict[str, Any] | None = None,
) -> Trajectory:
    """The `Trajectory` of a plan re-solved with the exact hybrid dynamics
    (`tfcontact.ocp.polish.PolishedPlan`, one frictional planar contact on flat ground).

    Its samples are the plan's nodes. tau is the physical time plus `IMPACT_TAU` per
    touchdown passed, so each touchdown is a frozen piece from its pre- to its post-impact
    node carrying the impulse; s = 1. Forces in the world frame: lambda_n along the
    ground's normal, lambda_t along x. `solver` and `task` are stored as the sidecar's
    entries of those names; `model` is `describe_robot(robot_spec, cls)`.
    """
    from tfcontact.ocp.polish import node_samples
    from tfcontact.timefreezing import FROZEN_RATE_TOL

    robot = robot_spec if isinstance(robot_spec, dict) else robot_spec.to_dict()
    scene = {"terrain": {"type": "flat", "height": 0.0}} if scene is None else dict(scene)
    if len(robot.get("contacts", [])) != 1:
        raise InvalidInput("a polished plan has one contact; the robot has "
                           f"{len(robot.get('contacts', []))}")
    samples = node_samples(plan, cls)
    n_q = cls.n_q
    clock = np.asarray(plan.t, dtype=float)
    tau = _node_tau(clock, clock)
    normal = np.asarray(scene.get("terrain", {}).get("normal", GROUND_NORMAL), dtype=float)
    tangent = np.array([1.0, 0.0, 0.0])

    def world(values: np.ndarray) -> np.ndarray:
        return (values[:, :1] * normal + values[:, 1:2] * tangent)[:, None, :]

    return Trajectory(
        tau=tau, clock=clock, s=np.ones_like(clock), q=plan.x[:, :n_q], v=plan.x[:, n_q:],
        u=samples["u"], gap=samples["gap"][:, None],
        normal_velocity=samples["normal_velocity"][:, None],
        force=world(samples["force"]), impulse=world(samples["impulse"]),
        status=plan.status, robot=_jsonable(robot), scene=_jsonable(scene),
        solver=_jsonable(solver or {}), verification=_jsonable(plan.verification.to_dict()),
        extras={"phase": np.array([{"stick": 0, "slip+": 1, "slip-": -1, "flight": 2}[m]
                                   for m in samples["mode"]])},
        model=describe_robot(robot, cls), task=_jsonable(task or {}),
        frozen_rate_tol=FROZEN_RATE_TOL,
    )


def _node_tau(times: np.ndarray, clock: np.ndarray) -> np.ndarray:
    """tau of a re-solved plan's nodes: `clock` plus `IMPACT_TAU` per impact passed, an
    impact being a node that repeats the time of the node before it in `times` (the two
    sides of a touchdown)."""
    return clock + IMPACT_TAU * np.concatenate([[0], np.cumsum(np.diff(times) == 0)])


def stance_clock(times: np.ndarray, solved: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """(clock, tau, drop) of a stance plan's nodes (`StancePlan.t`): the physical time,
    the numerical time (`IMPACT_TAU` per touchdown passed) and how far [s] a node lay
    behind the latest time before it, repaired (0: none). A failed solve's last iterate
    need not hold its rows: in solo12's planar jump from a perturbed start a piece's step
    length (a variable tied to its touchdown times) came out negative, and the failed plan
    could not be written. Such nodes keep the latest time so far, so the plan is saved
    with its failed status; the impacts are those of `times` (a repaired node is none).

    Raises:
        InvalidInput: a solved plan's times decrease (its rows would not hold).
    """
    times = np.asarray(times, dtype=float)
    latest = np.maximum.accumulate(times)
    drop = float(np.max(latest - times, initial=0.0))  # the furthest a node lies behind
    if drop > 0.0 and solved:
        raise InvalidInput(f"the solved stance plan's node times decrease (by {drop:.3g} s); "
                           "its rows do not hold")
    return latest, _node_tau(times, latest), drop


def trajectory_from_stances(
    plan: Any,
    cls: Any,
    robot_spec: Any,
    scene: dict[str, Any] | None = None,
    *,
    directions: Any = None,
    solver: dict[str, Any] | None = None,
    task: dict[str, Any] | None = None,
) -> Trajectory:
    """The `Trajectory` of a plan re-solved along a sequence of stances
    (`tfcontact.ocp.stances.StancePlan`, several contacts, one per robot contact).

    Its samples are the plan's nodes; tau is the physical time plus `IMPACT_TAU` per
    touchdown passed (a frozen piece carrying the impulses, as `trajectory_from_polished`),
    s = 1. Forces and impulses in the world frame along `directions` (as for
    `trajectory_from_result`: per contact (n_w, T_w) or a function of q; default the
    ground of `scene["terrain"]`). `extras["closed"]`: which contacts are closed.
    A failed plan whose node times decrease (its rows not holding) keeps each node at the
    latest time so far, noted as `solver["clock_repaired"]` (`stance_clock`'s drop [s]).

    Raises:
        InvalidInput: a solved plan whose node times decrease.
    """
    from tfcontact.ocp.stances import node_values
    from tfcontact.timefreezing import FROZEN_RATE_TOL

    robot = robot_spec if isinstance(robot_spec, dict) else robot_spec.to_dict()
    scene = {"terrain": {"type": "flat", "height": 0.0}} if scene is None else dict(scene)
    n_c = cls.n_contacts
    if len(robot.get("contacts", [])) != n_c:
        raise InvalidInput(f"the robot has {len(robot.get('contacts', []))} contacts and the "
                           f"plan's system {n_c}")
    if directions is None:
        directions = ground_directions(scene, cls)
    directions_at = directions if callable(directions) else (lambda _q: directions)
    values = node_values(plan, cls)
    n_q = cls.n_q
    clock, tau, drop = stance_clock(plan.t, plan.solved)
    if drop > 0:
        solver = {**(solver or {}), "clock_repaired": drop}

    def world(local: np.ndarray) -> np.ndarray:
        out = np.zeros((len(clock), n_c, 3))
        for k, qk in enumerate(plan.x[:, :n_q]):
            for i, (n_w, t_w) in enumerate(directions_at(qk)):
                t_w = np.asarray(t_w, dtype=float).reshape(3, -1)
                out[k, i] = (local[k, i, 0] * np.asarray(n_w, dtype=float).reshape(3)
                             + t_w @ local[k, i, 1:1 + t_w.shape[1]])
        return out

    return Trajectory(
        tau=tau, clock=clock, s=np.ones_like(clock), q=plan.x[:, :n_q], v=plan.x[:, n_q:],
        u=values["u"], gap=values["gap"], normal_velocity=values["normal_velocity"],
        force=world(values["force"]), impulse=world(values["impulse"]),
        status=plan.status, robot=_jsonable(robot), scene=_jsonable(scene),
        solver=_jsonable(solver or {}), verification=_jsonable(plan.verification.to_dict()),
        extras={"closed": values["closed"].astype(int)},
        model=describe_robot(robot, cls), task=_jsonable(task or {}),
        frozen_rate_tol=FROZEN_RATE_TOL,
    )


# ------------------------------------------------------------------ robot description

#: What each base of `tfcontact.robot.BASES` puts between the world and the URDF's root
#: link (the joint `root_joint`), with the names and units of its coordinates.
BASE_MEANINGS: dict[str, str] = {
    "fixed": "no base joint: the URDF's root link is welded to the world",
    "planar": "root_joint = prismatic X, prismatic Z, revolute Y (one Pinocchio composite "
              "joint) under the URDF's root link: q_base = (x [m], z [m], pitch [rad]), "
              "motion in the world x-z plane",
    "planar_xz": "root_joint = prismatic X, prismatic Z under the URDF's root link: "
                 "q_base = (x [m], z [m]), no rotation",
    "vertical": "root_joint = prismatic Z under the URDF's root link: q_base = (z [m]), a "
                "vertical rail",
    "floating": "root_joint = translation, then ZYX Euler angles under the URDF's root link: "
                "q_base = (x, y, z [m], yaw, pitch, roll [rad]), "
                "R = Rz(yaw) Ry(pitch) Rx(roll)",
}
_RATE_UNITS = {"m": "m/s", "rad": "rad/s", "-": "-"}
_FORCE_UNITS = {"m": "N", "rad": "N m", "-": "-"}


def urdf_location(source: str) -> tuple[str, Path]:
    """Where a `RobotSpec.source` is, found the way `tfcontact.robot.load_robot` finds it.

    Returns:
        (locate, file): locate is "path" (a URDF path, relative to the current folder or
        the repository), "project" (`robots/NAME.urdf` of the repository) or
        "example-robot-data" (that package's robot NAME); file is the URDF.

    Raises:
        RobotLoadError: the URDF cannot be found.
    """
    from tfcontact.robot import REPO_ROOT

    if source.endswith(".urdf") or "/" in source or os.sep in source:
        path = Path(source).expanduser()
        for candidate in [path] if path.is_absolute() else [Path.cwd() / path, REPO_ROOT / path]:
            if candidate.is_file():
                return "path", candidate
        raise RobotLoadError(f"URDF file `{source}` not found")
    project = REPO_ROOT / "robots" / f"{source}.urdf"
    if project.is_file():
        return "project", project
    from example_robot_data.robots_loader import ROBOTS
    from example_robot_data.utils import getModelPath

    if source not in ROBOTS or not ROBOTS[source].urdf_filename:
        raise RobotLoadError(f"`{source}` is neither a URDF path, a robot of the project's "
                             "`robots/` nor an example-robot-data URDF robot")
    loader = ROBOTS[source]
    sub = os.path.join(loader.path, loader.urdf_subpath, loader.urdf_filename)
    return "example-robot-data", Path(loader.model_path or getModelPath(sub)) / sub


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def describe_robot(robot_spec: Any, cls: Any) -> dict[str, Any]:
    """The sidecar's `model`: the robot of a plan described without the repository.

    Args:
        robot_spec: the `RobotSpec` (or its `to_dict()`) of the plan's robot.
        cls: the plan's `ComplementarityLagrangianSystem` (its q, v and control names;
            f_v(q, v, u) = B u - h(q, v) must be affine in u).

    Returns:
        `{"urdf": {"locate", "name", "sha256"}, "base", "base_meaning", "gravity" [m/s^2],
        "coordinates", "velocities", "controls"}`; each coordinate and velocity names its
        joint and unit; each control its unit, the joint of the first velocity entry it
        drives and `drives` = [{"velocity", "joint", "gain"}] (the nonzero entries of B's
        column). Gravity is the plan's own (from f_v at rest over the base's translation
        masses; the Pinocchio model's for a fixed base).

    Raises:
        InvalidInput: the CLS's coordinates are not the robot's.
        RobotLoadError: the URDF cannot be found.
    """
    from tfcontact.robot import RobotSpec, load_robot

    spec = robot_spec if isinstance(robot_spec, RobotSpec) else RobotSpec.from_dict(robot_spec)
    robot = load_robot(spec)
    model = robot.model
    if cls.n_q != model.nv:
        raise InvalidInput(f"the plan has {cls.n_q} coordinates but the robot `{spec.source}` "
                           f"({spec.base} base) has {model.nv}")
    locate, urdf = urdf_location(spec.source)
    dofs = dof_units(model, spec.base)
    q0, v0, u0 = np.zeros(cls.n_q), np.zeros(cls.n_q), np.zeros(cls.n_u)
    forces = cls.function("forces")
    at_rest = np.asarray(forces(q0, v0, u0), dtype=float).ravel()
    gains = np.column_stack([np.asarray(forces(q0, v0, e), dtype=float).ravel() - at_rest
                             for e in np.eye(cls.n_u)]) if cls.n_u else np.zeros((cls.n_q, 0))
    axes = {"x": 0, "y": 1, "z": 2}
    translations = [(i, axes[name]) for i, (name, _) in enumerate(BASE_COORDINATES[spec.base])
                    if name in axes]
    if translations:
        mass = np.asarray(cls.function("mass")(q0), dtype=float)
        gravity = [0.0, 0.0, 0.0]
        for i, axis in translations:
            gravity[axis] = float(at_rest[i] / mass[i, i])
    else:
        gravity = [float(g) for g in model.gravity.linear]
    controls = []
    for j, name in enumerate(cls.control_names):
        driven = [i for i in range(cls.n_q) if abs(gains[i, j]) > 1e-12]
        first = dofs[driven[0]] if driven else ("", "-")
        controls.append({"name": name, "unit": _FORCE_UNITS[first[1]], "joint": first[0],
                         "drives": [{"velocity": cls.v_names[i], "joint": dofs[i][0],
                                     "gain": float(gains[i, j])} for i in driven]})
    return _jsonable({
        "urdf": {"locate": locate, "name": spec.source, "sha256": file_sha256(urdf)},
        "base": spec.base,
        "base_meaning": BASE_MEANINGS[spec.base],
        "gravity": gravity,
        "coordinates": [{"name": cls.q_names[i], "unit": dofs[i][1], "joint": dofs[i][0]}
                        for i in range(cls.n_q)],
        "velocities": [{"name": cls.v_names[i], "unit": _RATE_UNITS[dofs[i][1]],
                        "joint": dofs[i][0]} for i in range(cls.n_q)],
        "controls": controls,
    })


# ------------------------------------------------------------------------ checks

#: Status words of a plan that solved and passed its verification.
SUCCESS_STATUSES = ("converged", "success")


@dataclass(frozen=True)
class CheckTolerances:
    """Tolerances of `check_plan`.

    Args:
        penetration: largest allowed penetration [m]: gaps >= -penetration on the physical
            samples (the plan verification's default).
        model: largest |stored gap - gap by forward kinematics| [m], and largest
            |M dv - sum J^T Lambda| per impact [N s] relative to max(1, |M dv|).
        closed_gap: a contact is closed at gap <= this [m] (impact detection).
        approach_speed: a closed contact approaches when its normal velocity is below
            -approach_speed [m/s] (impact detection).

    Raises:
        InvalidInput: a tolerance that is not a finite number > 0.
    """

    penetration: float = 1e-3
    model: float = 1e-6
    closed_gap: float = 1e-4
    approach_speed: float = 1e-2

    def __post_init__(self) -> None:
        for name in ("penetration", "model", "closed_gap", "approach_speed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not (math.isfinite(value) and value > 0):
                raise InvalidInput(f"`{name}` must be a finite number > 0, got {value!r}")


@dataclass(frozen=True, eq=False)
class RecordedImpact:
    """An impact found in a trajectory's recorded data (`find_impacts`).

    Attributes:
        time: physical time [s] of the impact.
        samples: (pre, post): the samples just before and just after it.
        kind: "frozen piece" (the clock stands still over samples pre..post while tau
            advances), "impulse" (a nonzero recorded impulse at `post` outside any frozen
            piece) or "inside interval" (a closed contact approaches at `pre`, the
            interval pre..post runs, and by `post` the contact has reached the ground
            (gap <= 0) or its approach slowed by more than the approach speed: the impact
            lies between two samples, too short for the sampling to show, and no impulse
            is recorded for it).
        contacts: the contacts closed at `pre` ("inside interval": those touching down:
            another foot of the pair may still be flying on towards the ground).
        impulse: the recorded impulses [N s] summed over the samples pre+1..post, (nc, 3).
    """

    time: float
    samples: tuple[int, int]
    kind: str
    contacts: tuple[int, ...]
    impulse: np.ndarray


def find_impacts(traj: Trajectory, *,
                 tolerances: CheckTolerances | None = None) -> tuple[RecordedImpact, ...]:
    """The impacts of a trajectory, from its recorded data alone (see `RecordedImpact`).

    Frozen pieces are found with the trajectory's own `frozen_rate_tol` (the sidecar's).
    """
    tol = tolerances or CheckTolerances()
    phys = physical_time(traj)
    frozen = np.zeros(traj.n_samples - 1, dtype=bool)
    impacts = []
    for pre, post in phys.frozen_index:
        frozen[pre:post] = True
        impacts.append((pre, post, "frozen piece"))
    explained = np.zeros(traj.n_samples, dtype=bool)
    for pre, post in phys.frozen_index:
        explained[pre + 1:post + 1] = True
    recorded = np.any(traj.impulse != 0.0, axis=(1, 2))
    for k in np.flatnonzero(recorded & ~explained):
        earlier = phys.index[phys.index < k]
        impacts.append((int(earlier[-1]) if earlier.size else 0, int(k), "impulse"))
    closed = traj.gap <= tol.closed_gap
    approaching = closed & (traj.normal_velocity < -tol.approach_speed)
    # a closed contact approaching at one sample touches down before the next only if it
    # reaches the ground by then or its approach is taken out: one that flies on towards
    # the ground is still in the air (a trot's swing foot 0.08 mm above the ground 1 ms
    # before its landing, measured)
    reached = (traj.gap[1:] <= 0.0) | (np.diff(traj.normal_velocity, axis=0)
                                       > tol.approach_speed)
    touching = approaching[:-1] & reached
    # an approach into a frozen piece that starts at the next sample is that piece's
    next_frozen = np.append(frozen[1:], False)
    for k in np.flatnonzero(np.any(touching, axis=1) & ~frozen & ~next_frozen):
        if not any(pre <= k < post for pre, post, _ in impacts):
            impacts.append((int(k), int(k) + 1, "inside interval"))
    return tuple(
        RecordedImpact(time=float(traj.clock[pre]), samples=(pre, post), kind=kind,
                       contacts=tuple(int(c) for c in np.flatnonzero(
                           touching[pre] if kind == "inside interval" else closed[pre])),
                       impulse=traj.impulse[pre + 1:post + 1].sum(axis=0))
        for pre, post, kind in sorted(impacts))


@dataclass(frozen=True)
class CheckItem:
    """One line of a plan check: its name, whether it passed, and what was measured."""

    name: str
    passed: bool
    detail: str

    def __str__(self) -> str:
        return f"{'ok  ' if self.passed else 'FAIL'} {self.name:8s} {self.detail}"


@dataclass(frozen=True, eq=False)
class PlanCheck:
    """The outcome of `check_plan`: one `CheckItem` per check, and the impacts found."""

    items: tuple[CheckItem, ...]
    impacts: tuple[RecordedImpact, ...]

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(item.passed for item in self.items)

    def __str__(self) -> str:
        return "\n".join(str(item) for item in self.items)


def check_plan(traj: Trajectory, *, tolerances: CheckTolerances | None = None) -> PlanCheck:
    """Check a plan's physics from its recorded data and its rebuilt robot.

    Checks: `status` (a success word, and the recorded verification not failed), `clock`
    (non-decreasing), `gaps` (>= -penetration on the physical samples: inside a frozen
    piece the auxiliary dynamics may pass through the ground), `robot` (rebuilt with
    `tfcontact.robot.load_robot` from the sidecar's `robot`; its nq and, when recorded,
    its URDF's SHA-256 match), `fk` (stored gaps = forward-kinematics gaps, on flat
    terrain) and `impacts` (`find_impacts`; each frozen piece or recorded impulse
    satisfies M(q-) (v+ - v-) = sum_c J_c(q-)^T Lambda_c with the recorded impulses;
    after an impact inside an interval the contact no longer approaches).

    Args:
        traj: the trajectory (e.g. from `load_trajectory`).
        tolerances: see `CheckTolerances`.

    Returns:
        The `PlanCheck`.
    """
    tol = tolerances or CheckTolerances()
    items = []
    verification = traj.verification.get("passed")
    words = {True: "passed", False: "FAILED", None: "not recorded"}
    items.append(CheckItem(
        "status", traj.status in SUCCESS_STATUSES and verification is not False,
        f"status {traj.status!r}, verification "
        f"{words.get(verification, repr(verification))}"))
    items.append(CheckItem("clock", bool(np.all(np.diff(traj.clock) >= 0)),
                           f"non-decreasing over {traj.n_samples} samples"))
    phys = physical_time(traj)
    lowest = float(phys.gap.min()) if phys.gap.size else 0.0
    items.append(CheckItem("gaps", lowest >= -tol.penetration,
                           f"min gap {lowest:+.2e} m on the physical samples "
                           f"(tolerance -{tol.penetration:.0e} m)"))
    impacts = find_impacts(traj, tolerances=tol)
    robot = _rebuilt(traj)
    if isinstance(robot, str):
        items.append(CheckItem("robot", False, robot))
        items.append(_impact_item(traj, impacts, None, tol))
        return PlanCheck(tuple(items), impacts)
    model = robot.model
    problems = []
    if model.nq != traj.q.shape[1]:
        problems.append(f"q has {traj.q.shape[1]} columns, the rebuilt model nq = {model.nq}")
    recorded = traj.model.get("urdf", {}).get("sha256")
    locate, urdf = urdf_location(traj.robot["source"])
    if recorded is not None and recorded != file_sha256(urdf):
        problems.append(f"the URDF {urdf} differs from the plan's (SHA-256 {recorded[:12]}...)")
    items.append(CheckItem("robot", not problems, "; ".join(problems) or
                           f"{traj.robot['source']} ({locate}: {urdf.name}), "
                           f"{traj.robot['base']} base, nq = {model.nq}"))
    if problems:
        return PlanCheck(tuple(items), impacts)
    items.append(_fk_item(traj, model, tol))
    items.append(_impact_item(traj, impacts, model, tol))
    return PlanCheck(tuple(items), impacts)


def _rebuilt(traj: Trajectory) -> Any:
    """The robot of the sidecar, or why it cannot be rebuilt."""
    from tfcontact.robot import RobotSpec, load_robot

    try:
        return load_robot(RobotSpec.from_dict(traj.robot))
    except TfcontactError as err:
        return f"cannot rebuild the robot {traj.robot.get('source')!r}: {err}"


def _contact_frames(traj: Trajectory, model: Any) -> list[tuple[int, float]]:
    return [(model.getFrameId(c["frame"]), float(c["radius"])) for c in traj.robot["contacts"]]


def _fk_item(traj: Trajectory, model: Any, tol: CheckTolerances) -> CheckItem:
    import pinocchio as pin

    terrain = traj.scene.get("terrain", {})
    if (terrain.get("type", "flat") != "flat" or traj.scene.get("boxes")
            or "cls_gaps" in traj.extras):
        return CheckItem("fk", True, "skipped: the gaps are not against one flat ground")
    normal = np.asarray(terrain.get("normal", (0.0, 0.0, 1.0)), dtype=float)
    normal /= np.linalg.norm(normal)
    height = float(terrain.get("height", 0.0))
    data = model.createData()
    frames = _contact_frames(traj, model)
    worst = 0.0
    for qk, gap in zip(traj.q, traj.gap, strict=True):
        pin.framesForwardKinematics(model, data, qk)
        for (frame, radius), g in zip(frames, gap, strict=True):
            worst = max(worst, abs(normal @ data.oMf[frame].translation - height - radius - g))
    return CheckItem("fk", worst <= tol.model,
                     f"max |gap - forward-kinematics gap| = {worst:.2e} m")


def _impact_item(traj: Trajectory, impacts: tuple[RecordedImpact, ...], model: Any,
                 tol: CheckTolerances) -> CheckItem:
    """Momentum balance of the frozen pieces and recorded impulses; the approach stopped
    after the impacts inside an interval."""
    import pinocchio as pin

    kinds = {kind: sum(i.kind == kind for i in impacts)
             for kind in ("frozen piece", "impulse", "inside interval")}
    text = (f"{len(impacts)} impact(s) ({kinds['frozen piece']} frozen pieces, "
            f"{kinds['impulse']} recorded impulses only, {kinds['inside interval']} inside a "
            "sampling interval without a recorded impulse)")
    if impacts:
        text += " at t = " + ", ".join(f"{i.time:.4g}" for i in impacts) + " s"
    still = [i for i in impacts if i.kind == "inside interval"
             and np.any(traj.normal_velocity[i.samples[1], list(i.contacts)]
                        < -tol.approach_speed)]
    worst = 0.0
    if model is not None:
        data = model.createData()
        frames = _contact_frames(traj, model)
        for imp in impacts:
            if imp.kind == "inside interval":
                continue
            pre, post = imp.samples
            qk = traj.q[pre]
            pin.computeJointJacobians(model, data, qk)
            pin.framesForwardKinematics(model, data, qk)
            mass = pin.crba(model, data, qk)
            mass = np.triu(mass) + np.triu(mass, 1).T
            momentum = mass @ (traj.v[post] - traj.v[pre])
            generalised = sum((pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3].T
                               @ imp.impulse[c] for c, (f, _) in enumerate(frames)),
                              np.zeros(model.nv))
            scale = max(1.0, float(np.max(np.abs(momentum))))
            worst = max(worst, float(np.max(np.abs(momentum - generalised))) / scale)
        text += f"; max |M dv - J^T Lambda| / max(1, |M dv|) = {worst:.2e}"
    else:
        text += "; momentum balance not checked (no robot)"
    if still:
        text += f"; the contact still approaches after t = {still[0].time:.4g} s"
    return CheckItem("impacts", worst <= tol.model and not still, text)
