"""Robot plans runnable from the command line: `tfcontact plan NAME --out DIR`.

Each plan states its OCP, solves it with time-freezing + FESD, verifies it, and writes
into DIR: `trajectory.npz` + `trajectory.json` (the viz layer's format), the figures and
`replay.html`, a standalone browser replay.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tfcontact.errors import InvalidInput


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
    in the trajectory's sidecar (its ground and obstacles)."""

    robot: Any
    problem: Any
    options: Any
    scene: dict


@dataclass(frozen=True)
class Plan:
    """A named robot plan: `build(task)` gives its `PlanSetup` (task None: the first)."""

    name: str
    summary: str
    build: Callable[[str | None], PlanSetup]
    tasks: tuple[str, ...]


def _flat(ground: Any) -> dict:
    return {"terrain": {"type": "flat", "height": float(ground.height),
                        "normal": [float(c) for c in ground.normal]}}


def _hopper(task: str | None) -> PlanSetup:
    from tfcontact.scenes.hopper import hopper_options, hopper_problem

    robot, ground, problem = hopper_problem(task or "short")
    return PlanSetup(robot, problem, hopper_options(task or "short"), _flat(ground))


def _monoped(task: str | None) -> PlanSetup:
    from tfcontact.scenes.monoped import monoped_options, monoped_problem

    mp = monoped_problem(task or "full")
    return PlanSetup(mp.robot, mp.problem, monoped_options(task or "full"), mp.scene())


PLANS: dict[str, Plan] = {
    "hopper": Plan(
        name="hopper",
        summary="planar one-legged hopper (robots/hopper.urdf), TF-8: jump to x = 0.7 "
                "(--task long: two jumps to x = 1.3)",
        build=_hopper,
        tasks=("short", "long"),
    ),
    "monoped": Plan(
        name="monoped",
        summary="Capler monoped (robots/monoped.urdf), TF-9: hop over three holes to x = 3 "
                "(--task reduced: one hole, to x = 1); not solved yet: its plans fail "
                "the verification (exit status 1)",
        build=_monoped,
        tasks=("full", "reduced"),
    ),
}


def run_plan(name: str, out_dir: Path | str, *, task: str | None = None,
             attempts: int | None = None, verbose: bool = True) -> PlanReport:
    """Solve the plan `name`, verify it and write trajectory, figures and replay to out_dir.

    `attempts` overrides the plan's number of solves (`ContactSolverOptions.attempts`).
    Files are written whatever the outcome (a failed plan's last iterate is saved with its
    status), so that no output is lost.
    """
    from tfcontact.ocp.contact import solve_contact
    from tfcontact.viz import plot_trajectory, replay, save_trajectory
    from tfcontact.viz.plan import trajectory_from_result

    if name not in PLANS:
        raise InvalidInput(f"unknown plan `{name}`; available: {', '.join(PLANS)}")
    plan = PLANS[name]
    if task is not None and task not in plan.tasks:
        raise InvalidInput(f"plan `{name}` has no task `{task}`; tasks: {', '.join(plan.tasks)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    setup = plan.build(task)
    robot, problem, options = setup.robot, setup.problem, setup.options
    if attempts is not None:
        options = dataclasses.replace(options, attempts=attempts)
    if verbose:
        print(f"plan {name} ({task or plan.tasks[0]}): {robot.model.name}, nq = {robot.nq}, "
              f"T = {problem.horizon} s, N = {problem.n_intervals}", flush=True)
    result = solve_contact(problem, options, verbose=verbose)
    trajectory = trajectory_from_result(result, robot.spec, setup.scene)
    npz, sidecar = save_trajectory(out / "trajectory.npz", trajectory)
    figures = plot_trajectory(trajectory, out)
    page = replay(trajectory, html=out / "replay.html", robot=robot)
    summary = result.summary()
    (out / "summary.json").write_text(json.dumps({
        "plan": name, "task": task or plan.tasks[0], "status": result.status,
        "success": result.success, "wall_time": time.perf_counter() - start,
        "summary": summary}, indent=2))
    files = (npz, sidecar, *figures, page.html, out / "summary.json")
    if verbose:
        print(f"wrote {len(files)} files to {out}/:")
        for f in files:
            print(f"  {f}")
        print(f"replay: open {page.html} in a browser (or `tfcontact replay {npz}`)")
    return PlanReport(name=name, success=result.success, status=result.status, out_dir=out,
                      files=tuple(Path(f) for f in files), summary=summary)
