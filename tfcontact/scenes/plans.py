"""Robot plans runnable from the command line: `tfcontact plan NAME --out DIR`.

Each plan states its OCP, solves it with time-freezing + FESD, verifies it, and writes
into DIR: `trajectory.npz` + `trajectory.json` (the viz layer's format), the figures and
`replay.html`, a standalone browser replay.
"""

from __future__ import annotations

import dataclasses
import json
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tfcontact.errors import InvalidInput, positive_int

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


@dataclass(frozen=True)
class PlanSetup:
    """What a plan needs to run: the robot, problem, solver options and the scene stored
    in the trajectory's sidecar (its ground and obstacles); `terrain`: the
    `tfcontact.robot.Terrain` the contacts' gaps model, if one (the trajectory's forces
    then follow its normal along the plan), else None (one plane: the scene's normal)."""

    robot: Any
    problem: Any
    options: Any
    scene: dict
    terrain: Any = None


@dataclass(frozen=True)
class PlanOutcome:
    """What a plan's own solver returns to `run_plan`: the trajectory to write, the robot
    for the replay, the status, a summary text and files it wrote itself."""

    trajectory: Any
    robot: Any
    status: str
    success: bool
    summary: str
    files: tuple[Path, ...] = ()
    task: dict | None = None  # the goals measured (`TaskReport.to_dict()`), if stated
    result: Any = None  # a discovery's `ContactResult`, for the stage after it
    setup: PlanSetup | None = None  # the problem the stage solved


@dataclass(frozen=True)
class StageInput:
    """What a stage of a plan's pipeline gets: the plan and task names, the staging
    folder, the user's settings and the outcome of the stage before (None first)."""

    plan: str
    task: str
    out: Path
    verbose: bool
    attempts: int | None
    previous: PlanOutcome | None


class Stage(ABC):
    """One step of a plan's pipeline (`Plan.stages`), run in turn by `run_plan`."""

    name: str
    takes_attempts: bool = True  # `run_plan(attempts=...)` applies to it

    @abstractmethod
    def run(self, given: StageInput) -> PlanOutcome:
        """The stage's outcome (the last stage's is written)."""


@dataclass(frozen=True)
class Discover(Stage):
    """Find the contact sequence: the time-freezing homotopy (`solve_contact`, with the
    plan's attempts) on the problem `build(task)` states, verified, goals checked."""

    build: Callable[[str | None], PlanSetup]
    name: str = "discover"

    def run(self, given: StageInput) -> PlanOutcome:
        from tfcontact.ocp.contact import solve_contact
        from tfcontact.plan_format import terrain_directions, trajectory_from_result

        setup = self.build(given.task)
        robot, problem, options = setup.robot, setup.problem, setup.options
        if given.attempts is not None:
            options = dataclasses.replace(options, attempts=given.attempts)
        if given.verbose:
            print(f"plan {given.plan} ({given.task}): {robot.model.name}, nq = {robot.nq}, "
                  f"T = {problem.horizon} s, N = {problem.n_intervals}", flush=True)
        result = solve_contact(problem, options, verbose=given.verbose)
        directions = (None if setup.terrain is None
                      else terrain_directions(robot, setup.terrain))
        trajectory = trajectory_from_result(result, robot.spec, setup.scene,
                                            directions=directions,
                                            task=result.task.to_dict())
        return PlanOutcome(trajectory, robot, result.status, result.success,
                           result.summary(), task=result.task.to_dict(), result=result,
                           setup=setup)


@dataclass(frozen=True)
class ExactResolve(Stage):
    """Re-solve the discovered plan exactly along its contact sequence (`tfcontact.ocp.
    polish`: the hybrid system's own modes, impacts at the found times, no time-freezing
    relaxation), verified against the exact-impact reference. One planar frictional
    contact (`polish` refuses others). `options`: `PolishOptions`; default: lift-offs at
    the nearest control jump."""

    options: Any = None
    name: str = "exact re-solve"

    def run(self, given: StageInput) -> PlanOutcome:
        from tfcontact.ocp.polish import PolishOptions, contact_phases, polish_contact
        from tfcontact.plan_format.adapters import trajectory_from_polished

        found = given.previous
        if found is None or found.result is None or found.setup is None:
            raise InvalidInput("an exact re-solve needs a discovery stage before it "
                               "(Plan stages (Discover(...), ExactResolve()))")
        if not found.result.ocp.success:  # the homotopy found no contact sequence to follow
            return found
        options = self.options or PolishOptions(lift_offs_at_control_jumps=True)
        problem, robot = found.setup.problem, found.setup.robot
        phases = contact_phases(found.result, options)
        plan = polish_contact(problem, phases, options, guess=found.result,
                              verbose=given.verbose)
        task = _polished_task(plan, problem)
        status = plan.status if not plan.success else \
            ("converged" if task.passed else task.status)
        summary = f"discovery: {found.status}\n{plan.summary()}\n{task.summary()}"
        solver = {"status": status, "objective": plan.cost,
                  "discovery": {"status": found.status, "cost": found.result.ocp.cost},
                  "phases": [dataclasses.asdict(p) for p in plan.phases],
                  "method": "exact re-solve along the discovered contact sequence "
                            "(tfcontact.ocp.polish)",
                  "steps_per_interval": list(plan.substeps)}
        trajectory = trajectory_from_polished(plan, problem.system.cls, robot.spec,
                                              found.setup.scene, solver=solver,
                                              task=task.to_dict())
        return PlanOutcome(trajectory, robot, status, plan.success and task.passed, summary,
                           task=task.to_dict(), setup=found.setup)


@dataclass(frozen=True)
class OwnSolver(Stage):
    """A scene's own solver, `solve(task, out, verbose)` (the monoped's chain)."""

    solve: Callable[[str, Path, bool], PlanOutcome]
    name: str = "own solver"
    takes_attempts: bool = False

    def run(self, given: StageInput) -> PlanOutcome:
        if given.attempts is not None:
            raise InvalidInput(f"plan `{given.plan}` has no attempts to set (its chain "
                               "restarts itself)")
        return self.solve(given.task, given.out, given.verbose)


@dataclass(frozen=True)
class Plan:
    """A named robot plan as data: its tasks and the stages `run_plan` runs in turn (e.g.
    discover the contact sequence, then re-solve exactly along it)."""

    name: str
    summary: str
    tasks: tuple[str, ...]
    stages: tuple[Stage, ...]

    def __post_init__(self) -> None:
        if not self.stages or not all(isinstance(s, Stage) for s in self.stages):
            raise InvalidInput(f"plan `{self.name}` needs stages (Discover, ExactResolve, "
                               "OwnSolver, ...)")

    @property
    def build(self) -> Callable[[str | None], PlanSetup] | None:
        """The problem builder of a plan that starts with a `Discover` (sweeps perturb
        its start), else None."""
        first = self.stages[0]
        return first.build if isinstance(first, Discover) else None


def _flat(ground: Any) -> dict:
    return {"terrain": {"type": "flat", "height": float(ground.height),
                        "normal": [float(c) for c in ground.normal]}}


def _hopper(task: str | None) -> PlanSetup:
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    robot, ground, problem = hopper_problem(task or "short")
    return PlanSetup(robot, problem, hopper_options(task or "short"), _flat(ground))


def _monoped(task: str, out: Path, verbose: bool) -> PlanOutcome:
    """The two-stage chain of `tfcontact.scenes.monoped_exact`: the time-freezing homotopy
    finds the reduced task's hop, the exact re-solve makes it a verified plan ("reduced"),
    tiled three times for TF-9's task on a searched schedule ("full") or on the hand-set
    one ("hand-set")."""
    from tfcontact.plan_format.adapters import trajectory_from_polished
    from tfcontact.scenes.monoped_exact import (
        HAND_SET_SCHEDULE,
        full_exact_plan,
        plot_exact_plan,
        reduced_exact_plan,
        save_exact_plan,
    )

    if task == "reduced":
        chain = reduced_exact_plan(verbose)
    else:  # "full": the hop schedule searched; "hand-set": the earlier verified route
        chain = full_exact_plan(verbose, schedule="search" if task == "full"
                                else HAND_SET_SCHEDULE)
    mp = chain.problem
    if verbose:
        print(chain.summary(), flush=True)
    if chain.plan is None:
        return PlanOutcome(None, mp.robot, chain.status, False, chain.summary())
    task = _polished_task(chain.plan, mp.problem)
    status = chain.status if not chain.success else \
        ("converged" if task.passed else task.status)
    summary = f"{chain.summary()}\n{task.summary()}"
    if verbose:
        print(task.summary(), flush=True)
    files = (save_exact_plan(chain.plan, out / "plan.npz"),
             plot_exact_plan(chain.plan, mp, out / "path.png"))
    solver = {"status": status, "message": chain.message,
              "objective": chain.plan.cost, "wall_time": chain.wall_time,
              "smallest_hole_value": chain.smallest_hole_value,
              "phases": [dataclasses.asdict(p) for p in chain.plan.phases],
              "steps": [dataclasses.asdict(step) for step in chain.steps],
              "method": "exact re-solve along a contact sequence (tfcontact.ocp.polish): "
                        + ("Radau IIA collocation" if chain.plan.integrator == "radau"
                           else "RK4 multiple shooting") + " on the fixed control grid",
              "steps_per_interval": list(chain.plan.substeps)}
    trajectory = trajectory_from_polished(chain.plan, mp.system.cls, mp.robot.spec,
                                          mp.scene(), solver=solver, task=task.to_dict())
    return PlanOutcome(trajectory, mp.robot, status, chain.success and task.passed, summary,
                       files, task=task.to_dict())


def _polished_task(plan: Any, problem: Any) -> Any:
    """The problem's goals measured on an exact re-solve's nodes (`TaskReport`)."""
    from tfcontact.ocp.goals import Motion, check_goals
    from tfcontact.ocp.polish import node_samples

    cls = problem.system.cls
    gaps = node_samples(plan, cls)["gap"].reshape(len(plan.t), -1)
    motion = Motion(t=np.asarray(plan.t), q=np.asarray(plan.x)[:, :cls.n_q], gaps=gaps,
                    names=cls.q_names)
    return check_goals(problem.goals, motion)


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
                "(about an hour; --task reduced: one hole, to x = 1, 6 min; --task "
                "hand-set: the hops on a hand-set schedule instead of a searched one): "
                "time-freezing homotopy, then the exact re-solve along its contact sequence",
        tasks=("full", "reduced", "hand-set"),
        stages=(OwnSolver(_monoped),),
    ),
}


def task_plan(source: str | Path) -> Plan:
    """The `Plan` of a task file (`tfcontact.task`): a path to a TOML file, or the name of
    a shipped task (`tfcontact.task.shipped_tasks()`).

    Raises:
        InvalidInput: no such task, or a bad field in it (named).
    """
    from tfcontact.task import build_task, load_task, shipped_tasks

    shipped = shipped_tasks()
    path = shipped.get(str(source), Path(source))
    if not str(path).endswith(".toml"):
        raise InvalidInput(f"unknown plan `{source}`; available: "
                           f"{', '.join([*PLANS, *shipped])}, or a task file PATH.toml")
    data = load_task(path)

    def build(_: str | None) -> PlanSetup:
        from tfcontact.robot import Terrain

        setup = build_task(data)
        terrain = setup.terrain if isinstance(setup.terrain, Terrain) else None
        return PlanSetup(setup.robot, setup.problem, setup.options, setup.scene, terrain)

    stages = (Discover(build), ExactResolve()) if data.exact_resolve else (Discover(build),)
    return Plan(name=data.name, summary=data.description or f"task file {path}",
                tasks=("task",), stages=stages)


def plan_named(name: str | Path) -> Plan:
    """The plan `name`: one of `PLANS`, a shipped task or a task file's path."""
    if isinstance(name, str) and name in PLANS:
        return PLANS[name]
    return task_plan(name)


def run_plan(name: str | Path, out_dir: Path | str, *, task: str | None = None,
             attempts: int | None = None, verbose: bool = True,
             force: bool = False) -> PlanReport:
    """Solve the plan `name`, verify it and write trajectory, figures and replay to out_dir.

    `name`: a plan of `PLANS`, a shipped task's name or a task file's path (`task_plan`).

    `attempts` overrides the plan's number of solves (`ContactSolverOptions.attempts`).
    The arguments and the output folder are checked before any solving
    (`OutputFolder.check`: a folder that already holds files is replaced only with
    `force`). The files are written into a staging folder and moved into place at once,
    whatever the outcome (a failed plan's last iterate is saved with its status); an
    interrupt (`tfcontact.errors.Interrupted`) leaves `out_dir` as it was.
    """
    from tfcontact.scenes.output import OutputFolder

    plan = plan_named(name)
    name = plan.name
    if task is not None and task not in plan.tasks:
        raise InvalidInput(f"plan `{name}` has no task `{task}`; tasks: {', '.join(plan.tasks)}")
    if attempts is not None:
        if not all(s.takes_attempts for s in plan.stages):
            raise InvalidInput(f"plan `{name}` has no attempts to set (its chain restarts "
                               "itself)")
        positive_int(attempts, "attempts")
    task = task or plan.tasks[0]
    folder = OutputFolder(Path(out_dir), force=force)
    folder.check()
    start = time.perf_counter()
    with folder.staging() as stage:
        outcome = None
        for step in plan.stages:
            if verbose and len(plan.stages) > 1:
                print(f"plan {name} ({task}): stage {step.name}", flush=True)
            outcome = step.run(StageInput(name, task, stage, verbose, attempts, outcome))
        collisions, collision_files = _collisions(outcome, stage)
        if collisions.get("passed") is False:
            # a physical, verified plan whose knee or base goes through the terrain (or
            # through the robot) is not a plan: the body and time are in the summary
            outcome = dataclasses.replace(
                outcome, success=False, status=COLLISION,
                summary=f"{outcome.summary}\ncollisions FAILED: {collisions['worst']}")
        files = _write_outcome(name, task, stage, start, outcome, collisions,
                               collision_files)
    files = [folder.final_path(f, stage) for f in files]
    if verbose:
        print(f"wrote {len(files)} files to {folder.target}/:")
        for f in files:
            print(f"  {f}")
        if outcome.trajectory is not None:
            print(f"replay: open {folder.target / 'replay.html'} in a browser (or "
                  f"`tfcontact replay {folder.target / 'trajectory.npz'}`)")
        print(f"plan {name} ({task}): {outcome.status}")
    return PlanReport(name=name, success=outcome.success, status=outcome.status,
                      out_dir=folder.target, files=tuple(files), summary=outcome.summary)


def _write_outcome(name: str, task: str, out: Path, start: float, outcome: PlanOutcome,
                   collisions: dict, collision_files: list[Path]) -> list[Path]:
    """Write the trajectory, figures, replay and summary.json of a solved (or failed) plan
    into `out`; returns the paths written."""
    from tfcontact.plan_format import save_trajectory
    from tfcontact.viz import plot_trajectory, replay

    files = [*outcome.files, *collision_files]
    if outcome.trajectory is not None:
        npz, sidecar = save_trajectory(out / "trajectory.npz", outcome.trajectory)
        figures = plot_trajectory(outcome.trajectory, out)
        page = replay(outcome.trajectory, html=out / "replay.html", robot=outcome.robot)
        files += [npz, sidecar, *figures, page.html]
    (out / "summary.json").write_text(json.dumps({
        "plan": name, "task": task, "status": outcome.status,
        "success": outcome.success, "wall_time": time.perf_counter() - start,
        "task_checks": outcome.task, "summary": outcome.summary,
        "collisions": collisions}, indent=2))
    files.append(out / "summary.json")
    return [Path(f) for f in files]


def _collisions(outcome: PlanOutcome, out: Path) -> tuple[dict, list[Path]]:
    """The URDF's full collision model along the plan against its scene's terrain
    (`tfcontact.viz.collision_figure.trajectory_collisions`): reported in summary.json and
    `collisions.png`; a body through the terrain or the robot fails the plan."""
    from tfcontact.viz.collision_figure import save_collision_figure, trajectory_collisions

    if outcome.trajectory is None:
        return {"checked": False, "reason": "no trajectory"}, []
    try:
        report = trajectory_collisions(outcome.trajectory, robot=outcome.robot)
    except InvalidInput as err:  # a scene terrain without an obstacle form
        return {"checked": False, "reason": str(err)}, []
    return report.to_dict(), [save_collision_figure(report, out / "collisions.png")]
