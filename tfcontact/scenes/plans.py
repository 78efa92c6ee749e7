"""Robot plans runnable from the command line: `tfcontact plan NAME --out DIR`.

Each plan is data (`PLANS`, or a task file: `task_plan`), its stages run in turn by
`run_plan` (the one pipeline, `tfcontact.scenes.pipeline`), which writes into DIR:
`trajectory.npz` + `trajectory.json` (the viz layer's format), the figures,
`replay.html` (a standalone browser replay), `summary.json`, and for an exact re-solve
its node file `plan.npz` (`tfcontact.plan_format.resolved`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.ocp.stances import StanceOptions
from tfcontact.scenes import monoped_exact
from tfcontact.scenes.pipeline import (
    Discover,
    ExactResolve,
    GivenStances,
    Plan,
    PlanOutcome,
    PlanSetup,
    Stage,
    StanceResolve,
    run_stages,
)
from tfcontact.verify import AutoReplay, MultiContactReplay

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    import numpy as np

    from tfcontact.ocp.gait import GaitReport
    from tfcontact.robot import Ground
    from tfcontact.task import Task

COLLISION = "collision"
"""The status of a plan whose robot goes through the terrain or through itself."""


@dataclass(frozen=True)
class PlanReport:
    """What a plan run wrote and how it went."""

    name: str
    success: bool
    status: str
    out_dir: Path
    files: tuple[Path, ...]
    summary: str


def _flat(ground: Ground) -> dict:
    return {"terrain": {"type": "flat", "height": float(ground.height),
                        "normal": [float(c) for c in ground.normal]}}


def _hopper(task: str | None) -> PlanSetup:
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    robot, ground, problem = hopper_problem(task or "short")
    return PlanSetup(robot, problem, hopper_options(task or "short"), _flat(ground))


PLANS: dict[str, Plan] = {
    "hopper": Plan(
        name="hopper",
        summary="planar one-legged hopper (robots/hopper.urdf), TF-8: jump to x = 0.7 "
                "(--task long: two jumps to x = 1.3)",
        tasks=("short", "long"),
        stages=(Discover(_hopper),),
    ),
    "hopper-exact": Plan(
        name="hopper-exact",
        summary="the hopper's one-hop bench task (to x = 1 in 1 s): discovered by the "
                "time-freezing homotopy, then re-solved exactly along its contact sequence",
        tasks=("bench",),
        stages=(Discover(_hopper), ExactResolve()),
    ),
    "monoped": Plan(
        name="monoped",
        summary="Capler monoped (robots/monoped.urdf), TF-9: hop over three holes to x = 3 "
                "(about 5 min; --task reduced: one hole, to x = 1, about 1 min; --task "
                "terrain: the holes as the terrain's, about 7.5 min; --task hand-set: the "
                "hops on a hand-set schedule instead of a searched one): time-freezing "
                "homotopy on the reduced task, then exact re-solves along its contact "
                "sequence (tfcontact.scenes.monoped_exact); round-off decides whether the "
                "reduced hop is found: where it is not (a Zen 3 EPYC), every task fails "
                "(README, known limits)",
        tasks=("full", "reduced", "terrain", "hand-set"),
        stages=monoped_exact.STAGES,
    ),
}


def task_plan(source: str | Path | Task) -> Plan:
    """The `Plan` of a task (`tfcontact.task`): a path to a TOML file, the name of a
    shipped task (`tfcontact.task.shipped_tasks()`) or a `Task` built in Python (e.g. a
    shipped one changed with `dataclasses.replace`).

    Raises:
        InvalidInput: no such task, or a bad field in it (named).
    """
    from tfcontact.task import (
        Task,
        discovery_path_rows,
        load_task,
        resolve_path_rows,
        shipped_tasks,
        solver_options,
        task_stances,
    )

    if isinstance(source, Task):
        data, origin = source, f"task `{source.name}`"
    else:
        shipped = shipped_tasks()
        path = shipped.get(str(source), Path(source))
        if not str(path).endswith(".toml"):
            raise InvalidInput(f"unknown plan `{source}`; available: "
                               f"{', '.join([*PLANS, *shipped])}, or a task file PATH.toml")
        data, origin = load_task(path), f"task file {path}"
    # one contact: its sequence with slip phases (`polish`); several: the stances found,
    # where the no-slip rows hold by construction (an open no-slip contact keeps
    # v_t^2 <= K gap: it does not skim the ground) and the reach rows are kept
    gains = tuple(c.no_slip_gain if c.no_slip else None for c in data.contacts)
    resolve = (ExactResolve() if len(data.contacts) == 1 and not data.stances else StanceResolve(
        StanceOptions(open_slip_gains=gains,
                      nodes=data.resolve_elements or StanceOptions.nodes, **data.resolve),
        path_rows=resolve_path_rows(data)))

    def build(_: str | None) -> PlanSetup:
        return _task_setup(data, data.exact_resolve)

    discover: tuple[Stage, ...] = (Discover(build, path_rows=discovery_path_rows(data)),)
    if data.continuation is not None:  # the other task's discovery first, then this one
        before = data.continuation.task
        discover = (Discover(lambda _: _task_setup(before, data.exact_resolve),
                             name=f"discover {before.name}",
                             path_rows=discovery_path_rows(before)),
                    Discover(build, continue_sigma=data.continuation.sigma,
                             path_rows=discovery_path_rows(data)))
    if data.stances:  # the sequence is given: solved along it, no discovery
        return Plan(name=data.name, summary=data.description or origin,
                    tasks=("task",), stages=(GivenStances(
                        build, task_stances(data), resolve.options, resolve.path_rows),))
    if not data.exact_resolve:
        return Plan(name=data.name, summary=data.description or origin,
                    tasks=("task",), stages=discover)
    # the re-solved plan is the plan: a failed one runs the whole pipeline again
    runs = solver_options(data).attempts
    return Plan(name=data.name, summary=data.description or origin,
                tasks=("task",), stages=(*discover, resolve), whole_attempts=runs)


def _task_setup(data: Task, exact_resolve: bool) -> PlanSetup:
    """The `PlanSetup` of a task: its robot, problem, solver options, scene and terrain;
    `exact_resolve`: a stance re-solve follows the discovery (whose verification is then
    the multi-contact reference's alone)."""
    from tfcontact.robot import Terrain
    from tfcontact.task import build_task

    setup = build_task(data)
    terrain = setup.terrain if isinstance(setup.terrain, Terrain) else None
    cls = setup.problem.system.cls

    def from_start(q0: np.ndarray, v0: np.ndarray) -> Any:
        # the task stated from there: its tracked splines begin at the new start
        start = dict(zip((*cls.q_names, *cls.v_names),
                         (float(v) for v in (*q0, *v0)), strict=True))
        return build_task(dataclasses.replace(data, start=start)).problem

    options = setup.options
    if (exact_resolve and len(data.contacts) > 1
            and isinstance(options.verify.replay, AutoReplay)
            and MultiContactReplay.applies_to(cls)):
        # the discovery's relaxed plan is the stance re-solve's guess, whose own
        # verification decides: no FESD re-simulation when the multi-contact reference
        # stops on it (solo12's jump: more than 15 minutes, after an 820 s discovery)
        options = dataclasses.replace(options, verify=dataclasses.replace(
            options.verify, replay=MultiContactReplay()))
    return PlanSetup(setup.robot, setup.problem, options, setup.scene, terrain,
                     start_ranges=dict(data.start_ranges) or None,
                     from_start=from_start)


def plan_named(name: str | Path | Task) -> Plan:
    """The plan `name`: one of `PLANS`, a shipped task, a task file's path or a `Task`."""
    if isinstance(name, str) and name in PLANS:
        return PLANS[name]
    return task_plan(name)


def run_plan(name: str | Path | Task, out_dir: Path | str, *, task: str | None = None,
             attempts: int | None = None, verbose: bool = True,
             force: bool = False) -> PlanReport:
    """Solve the plan `name`, verify it and write trajectory, figures and replay to out_dir.

    `name`: a plan of `PLANS`, a shipped task's name, a task file's path or a `Task`
    (`task_plan`).

    `attempts` overrides the plan's number of solves (`ContactSolverOptions.attempts`).
    The arguments and the output folder are checked before any solving
    (`OutputFolder.check`: a folder that already holds files is replaced only with
    `force`). The files are written into a staging folder and moved into place at once,
    whatever the outcome (a failed plan's last iterate is saved with its status); an
    interrupt (`tfcontact.errors.Interrupted`) leaves `out_dir` as it was.
    """
    from tfcontact.scenes.output import OutputFolder
    from tfcontact.viz.collision_figure import save_collision_figure

    plan = plan_named(name)
    name = plan.name
    if task is not None and task not in plan.tasks:
        raise InvalidInput(f"plan `{name}` has no task `{task}`; tasks: {', '.join(plan.tasks)}")
    if attempts is not None:
        if not any(isinstance(s, Discover) for s in plan.stages):
            raise InvalidInput(f"plan `{name}` has no discovery whose attempts could be set")
        positive_int(attempts, "attempts")
    task = task or plan.tasks[0]
    folder = OutputFolder(Path(out_dir), force=force)
    folder.check()
    start = time.perf_counter()
    stages = plan.stages_for(task)
    with folder.staging() as stage:
        if plan.whole_attempts is None:
            outcome, stage_times, collisions, report = run_checked(
                name, task, stages, stage, verbose=verbose, attempts=attempts)
        else:  # the whole pipeline again, each discovery one solve from its own seed
            outcome, stage_times, collisions, report = run_whole(
                attempts or plan.whole_attempts,
                lambda seed: run_checked(name, task, stages, stage, verbose=verbose,
                                         attempts=1, seed=seed),
                plan=name, task=task, verbose=verbose)
        collision_files = ([] if report is None
                           else [save_collision_figure(report, stage / "collisions.png")])
        gait = gait_report(outcome)
        files = _write_outcome(name, task, stage, start, outcome, collisions,
                               collision_files, stage_times, gait)
    files = [folder.final_path(f, stage) for f in files]
    if verbose:
        if gait is not None:
            print(gait.line())
        print(f"wrote {len(files)} files to {folder.target}/:")
        for f in files:
            print(f"  {f}")
        if outcome.trajectory is not None:
            print(f"replay: open {folder.target / 'replay.html'} in a browser (or "
                  f"`tfcontact replay {folder.target / 'trajectory.npz'}`)")
        print(f"plan {name} ({task}): {outcome.status}")
    return PlanReport(name=name, success=outcome.success, status=outcome.status,
                      out_dir=folder.target, files=tuple(files), summary=outcome.summary)


def gait_report(outcome: PlanOutcome, height: float = 0.01) -> GaitReport | None:
    """The gait of a plan with two contacts or more (`tfcontact.ocp.gait.name_gait`):
    which feet lift above `height` [m] together, each foot's side read from its place
    relative to the base at the start; None without a trajectory or robot (or one whose
    model does not fit the trajectory's q)."""
    import numpy as np
    import pinocchio as pin

    from tfcontact.ocp.gait import name_gait
    from tfcontact.plan_format import physical_time

    traj, robot = outcome.trajectory, outcome.robot
    contacts = [] if traj is None else traj.robot.get("contacts", [])
    if robot is None or len(contacts) < 2 or robot.model.nq != traj.q.shape[1]:
        return None
    model, data = robot.model, robot.model.createData()
    pin.framesForwardKinematics(model, data, traj.q[0])
    base = data.oMf[model.getFrameId("root_joint" if model.existFrame("root_joint")
                                     else "universe")]
    offsets = [base.actInv(data.oMf[model.getFrameId(c["frame"])]).translation
               for c in contacts]
    phys = physical_time(traj)
    return name_gait(phys.t, phys.gap, [c["frame"] for c in contacts], np.array(offsets),
                     height=height)


def _write_outcome(name: str, task: str, out: Path, start: float, outcome: PlanOutcome,
                   collisions: dict, collision_files: list[Path],
                   stage_times: list[dict], gait: GaitReport | None = None) -> list[Path]:
    """Write the trajectory, figures, replay and summary.json of a solved (or failed) plan
    into `out`; returns the paths written. `stage_times`: each stage's name, status,
    iterations and seconds; the writing's own seconds are added; `gait`: the plan's gait
    (`gait_report`), written as summary.json's "gait"."""
    from tfcontact.plan_format import save_trajectory
    from tfcontact.plan_format.resolved import save_resolved_plan
    from tfcontact.viz import plot_trajectory, replay

    files = list(collision_files)
    if outcome.chain is not None and outcome.chain.plan is not None:
        # the exact re-solve's nodes, re-verifiable from disk (`verify_polished`)
        files.append(save_resolved_plan(outcome.chain.plan, out / "plan.npz"))
    began = time.perf_counter()
    if outcome.trajectory is not None:
        npz, sidecar = save_trajectory(out / "trajectory.npz", outcome.trajectory)
        figures = plot_trajectory(outcome.trajectory, out)
        page = replay(outcome.trajectory, html=out / "replay.html", robot=outcome.robot)
        files += [npz, sidecar, *figures, page.html]
    (out / "summary.json").write_text(json.dumps({
        "plan": name, "task": task, "status": outcome.status,
        "success": outcome.success, "wall_time": time.perf_counter() - start,
        "stages": [*stage_times, {"stage": "files (trajectory, figures, replay)",
                                  "status": "written",
                                  "seconds": time.perf_counter() - began}],
        "task_checks": outcome.task, "summary": outcome.summary,
        "gait": None if gait is None else gait.to_dict(),
        "collisions": collisions}, indent=2))
    files.append(out / "summary.json")
    return [Path(f) for f in files]


def run_checked(plan: str, task: str, stages: Sequence[Stage], out: Path, *,
                verbose: bool = False, attempts: int | None = None,
                outcome: PlanOutcome | None = None, seed: int = 0
                ) -> tuple[PlanOutcome, list[dict], dict, Any]:
    """`run_stages`, then `check_collisions` on the last outcome, as `tfcontact plan` and
    a sweep's case run a plan: the outcome, each stage's entry (the collision check's
    last), the collision dict and report."""
    outcome, times = run_stages(plan, task, stages, out, verbose=verbose,
                                attempts=attempts, outcome=outcome, seed=seed)
    began = time.perf_counter()
    outcome, collisions, report = check_collisions(outcome)
    times.append({"stage": "collision check", "status": collisions.get("status",
                                                                       "not checked"),
                  "ran": True, "seconds": time.perf_counter() - began})
    return outcome, times, collisions, report


def run_whole(runs: int, run_once: Callable[[int], tuple[PlanOutcome, list[dict], dict, Any]],
              *, plan: str, task: str, verbose: bool = False
              ) -> tuple[PlanOutcome, list[dict], dict, Any]:
    """Run a whole plan (`run_once(seed)`: its stages, discovery first, and the collision
    check, as `run_checked` returns them) up to `runs` times, seeds 0, 1, ..., until its
    outcome succeeds (`Plan.whole_attempts`). Returns the last run's outcome, collision
    dict and report, and every run's stage entries, each with its `run` (1, 2, ...)."""
    positive_int(runs, "attempts")
    entries: list[dict] = []
    for seed in range(runs):
        outcome, times, collisions, report = run_once(seed)
        entries += [{**entry, "run": seed + 1} for entry in times]
        if outcome.success:
            break
        if verbose and seed + 1 < runs:
            print(f"plan {plan} ({task}): run {seed + 1} of {runs} ended {outcome.status}; "
                  f"the whole plan again, its discovery from a guess perturbed with seed "
                  f"{seed + 1}", flush=True)
    return outcome, entries, collisions, report


def check_collisions(outcome: PlanOutcome) -> tuple[PlanOutcome, dict, Any]:
    """The URDF's full collision model along the outcome's plan against its scene's
    terrain (`tfcontact.viz.collision_figure.trajectory_collisions`).

    Returns:
        The outcome (failed with status "collision" when a body goes through the terrain
        or the robot: a physical, verified plan whose knee or base does is not a plan; an
        outcome that failed already keeps its status, the first cause, e.g. a discovery's
        nlp_failed whose iterate lies in the ground; the body and time are added to the
        summary either way), the report as a dict for summary.json, and the
        `CollisionReport` (None when nothing was checked)."""
    from tfcontact.viz.collision_figure import trajectory_collisions

    if outcome.trajectory is None:
        return outcome, {"checked": False, "reason": "no trajectory"}, None
    try:
        report = trajectory_collisions(outcome.trajectory, robot=outcome.robot)
    except InvalidInput as err:  # a scene terrain without an obstacle form
        return outcome, {"checked": False, "reason": str(err)}, None
    collisions = report.to_dict()
    if collisions.get("passed") is False:
        outcome = dataclasses.replace(
            outcome, success=False, status=COLLISION if outcome.success else outcome.status,
            summary=f"{outcome.summary}\ncollisions FAILED: {collisions['worst']}")
    return outcome, collisions, report
