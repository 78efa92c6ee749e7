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
  (`tfcontact.ocp.verify.contact_impulses`), at the interval's first sample.

Impulses and forces are given in the world frame: Lambda_n n_w + Lambda_t T_w with the
world normal n_w and tangents T_w of each contact (`directions`; default: flat ground,
n_w = z, T_w = x (planar) or (x, y)). Several CLS contacts may belong to one robot contact
(a ball in a box: four walls, one ball): their gap is the smallest, their normal velocity
the one of the nearest wall, their forces and impulses add up (`contact_map`), and the
per-CLS-contact gaps are kept as the extra array `cls_gaps`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.viz.trajectory import Trajectory

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
    end_state_deviation).
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
    return [dataclasses.asdict(a) for a in getattr(result, "attempts", ())]


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


def trajectory_from_result(
    result: Any,
    robot_spec: Any,
    scene: dict[str, Any] | None = None,
    *,
    directions: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    contact_map: Sequence[int] | None = None,
    closed_gap: float = 1e-3,
) -> Trajectory:
    """The `Trajectory` of a solved contact plan (module docstring).

    Main args:
        result: a `ContactResult` from `tfcontact.ocp.contact.solve_contact`.
        robot_spec: the `tfcontact.robot.RobotSpec` (or its `to_dict()`) that rebuilds the
            robot whose configuration is the plan's q (q in the robot's own coordinates).
        scene: the scene dict (terrain, boxes, holes); default flat ground at height 0.

    Other args:
        directions: per CLS contact, (n_w (3,), T_w (3, n_t)): world normal and tangents
            used to express impulses and forces in the world frame; default the ground of
            `scene["terrain"]` (its "normal", default z; tangents as `robot.Ground`).
        contact_map: per CLS contact, the index of the robot contact it belongs to; default
            one to one, or all to the single robot contact.
        closed_gap: a contact is closed, and may carry a force, where its gap <= this [m].

    Returns:
        The `Trajectory` (status = `result.status`; solver = `solver_record(result)`;
        verification = `result.verification.to_dict()`).

    Raises:
        InvalidInput: the robot's contacts cannot be matched with the CLS's contacts.
    """
    from tfcontact.ocp.verify import contact_impulses

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
        from tfcontact.robot import Ground

        terrain = scene.get("terrain", {})
        ground = Ground(normal=tuple(terrain.get("normal", GROUND_NORMAL)))
        directions = [(np.asarray(ground.normal),
                       ground.tangents(c.n_tangents == 1) if c.n_tangents else np.zeros((3, 0)))
                      for c in cls.contacts]
    directions = [(np.asarray(n, float).reshape(3), np.asarray(t, float).reshape(3, -1))
                  for n, t in directions]
    if len(directions) != n_c:
        raise InvalidInput(f"`directions` has {len(directions)} entries, expected {n_c}")

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

    def world(lam_n: float, lam_t: np.ndarray, i: int) -> np.ndarray:
        n_w, t_w = directions[i]
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
    for imp in result.physical.impacts:
        k = boundary[imp.index[1]] if imp.index[1] < boundary.size else n - 1
        for i in range(n_c):
            n_t = cls.contacts[i].n_tangents
            impulse[k, contact_map[i]] += world(imp.normal_impulse[i],
                                                imp.tangential_impulse[i, :n_t], i)

    # forces on running intervals with a closed contact, from the momentum balance
    force = np.zeros((n, n_robot, 3))
    dt = np.diff(clock)
    running = dt > 1e-3 * np.maximum(np.diff(tau), 1e-300)
    mass = cls.function("mass")
    forces = cls.function("forces")
    tangents = [cls.function(f"tangents_{i}") for i in range(n_c)]

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
            force[k, contact_map[i]] += world(lam[col], lam[col + 1 : col + 1 + n_t], i)
            col += 1 + n_t

    verification = result.verification.to_dict()
    return Trajectory(
        tau=tau, clock=clock, s=s, q=q, v=v, u=u, gap=gap, normal_velocity=normal_velocity,
        force=force, impulse=impulse, status=result.status, robot=_jsonable(robot),
        scene=_jsonable(scene), solver=solver_record(result),
        verification=_jsonable(verification),
        extras={"cls_gaps": gaps_all} if n_c != n_robot else {},
    )


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


def save_plan(
    result: Any,
    trajectory: Trajectory,
    out_dir: str | Path,
    *,
    formats: tuple[str, ...] = ("png",),
) -> list[Path]:
    """Write a plan's files into `out_dir` (created): `trajectory.npz` + `trajectory.json`,
    the standard figures of `plot_trajectory` (frozen pieces detected with the
    time-freezing layer's `FROZEN_RATE_TOL`) and `summary.json` (`plan_summary`).

    Returns:
        The paths written.
    """
    from tfcontact.timefreezing import FROZEN_RATE_TOL
    from tfcontact.viz.figures import plot_trajectory
    from tfcontact.viz.trajectory import save_trajectory

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = list(save_trajectory(out / "trajectory.npz", trajectory, rate_tol=FROZEN_RATE_TOL))
    files += plot_trajectory(trajectory, out, formats=formats, rate_tol=FROZEN_RATE_TOL)
    summary = out / "summary.json"
    summary.write_text(json.dumps(plan_summary(result), indent=2, allow_nan=False) + "\n")
    files.append(summary)
    return files


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
) -> Trajectory:
    """The `Trajectory` of a plan re-solved with the exact hybrid dynamics
    (`tfcontact.ocp.polish.PolishedPlan`, one frictional planar contact on flat ground).

    Its samples are the plan's nodes. tau is the physical time plus `IMPACT_TAU` per
    touchdown passed, so each touchdown is a frozen piece from its pre- to its post-impact
    node carrying the impulse; s = 1. Forces in the world frame: lambda_n along the
    ground's normal, lambda_t along x. `solver` is stored as the sidecar's solver entry.
    """
    from tfcontact.ocp.polish import node_samples

    robot = robot_spec if isinstance(robot_spec, dict) else robot_spec.to_dict()
    scene = {"terrain": {"type": "flat", "height": 0.0}} if scene is None else dict(scene)
    if len(robot.get("contacts", [])) != 1:
        raise InvalidInput("a polished plan has one contact; the robot has "
                           f"{len(robot.get('contacts', []))}")
    samples = node_samples(plan, cls)
    n_q = cls.n_q
    clock = np.asarray(plan.t, dtype=float)
    impacts = np.concatenate([[0], np.cumsum(np.diff(clock) == 0)])
    tau = clock + IMPACT_TAU * impacts
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
    )
