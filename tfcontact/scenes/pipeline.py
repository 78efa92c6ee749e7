"""The one pipeline of every plan: a plan is data (`Plan`: tasks and stages), each stage
gets the outcome of the stage before and returns its own (`PlanOutcome`); `run_plan`
(`tfcontact.scenes.plans`) runs them in turn and writes the last outcome.

Stages: `Discover` finds the contact sequence with the time-freezing homotopy;
`StanceResolve` re-solves a plan with several contacts exactly along the stances found;
`GivenStances` solves one along a contact sequence given as data, without a discovery;
`ExactResolve` re-solves along a contact sequence exactly, level after level
(`tfcontact.ocp.chain`), from where its `ResolveStart` says (`FoundSequence`: the
discovery's sequence; `PreviousPlan`: the exact plan before; a scene's own rule, e.g. the
monoped's hop tiled on a schedule). A scene adds its own starts and levels as data, not a
pipeline of its own.
"""

from __future__ import annotations

import dataclasses
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tfcontact.errors import InvalidInput, positive_int
from tfcontact.ocp.chain import ChainStep, ResolveChain, ResolveLevel, resolve_chain
from tfcontact.ocp.goals import Goal, LiftOffs
from tfcontact.ocp.polish import Phase, PolishedPlan, PolishOptions, contact_phases
from tfcontact.ocp.stances import (
    Stance,
    StanceOptions,
    StancePlan,
    resolve_stances,
    schedule_of,
)

if TYPE_CHECKING:
    from tfcontact.ocp.contact import ContactProblem, ContactResult, ContactSolverOptions
    from tfcontact.ocp.goals import TaskReport
    from tfcontact.plan_format import Trajectory
    from tfcontact.robot import Robot, Terrain


@dataclass(frozen=True)
class PlanSetup:
    """What a plan needs to run: the robot, problem, solver options and the scene stored
    in the trajectory's sidecar (its ground and obstacles); `terrain`: the
    `tfcontact.robot.Terrain` the contacts' gaps model, if one (the trajectory's forces
    then follow its normal along the plan), else None (one plane: the scene's normal).
    `options`: the discovery's `ContactSolverOptions` (None for a setup only re-solved
    exactly). `start_ranges`: {name: (low, high)} offsets a stability sweep draws for the
    start (a task's `start_ranges`); None: the sweep's defaults. `from_start`: (q0, v0) ->
    the problem planned from that start as its user would state it (a task file's
    reference splines then begin there); None: `problem` with only q0 and v0 replaced."""

    robot: Robot
    problem: ContactProblem
    options: ContactSolverOptions | None
    scene: dict
    terrain: Terrain | None = None
    start_ranges: dict[str, tuple[float, float]] | None = None
    from_start: Callable[[np.ndarray, np.ndarray], ContactProblem] | None = None

    def problem_from(self, q0: np.ndarray, v0: np.ndarray) -> ContactProblem:
        """The problem planned from the start (q0, v0): `from_start`'s, else `problem`
        with only its start state replaced."""
        q0, v0 = np.asarray(q0, dtype=float), np.asarray(v0, dtype=float)
        if self.from_start is not None:
            return self.from_start(q0, v0)
        return dataclasses.replace(self.problem, q0=q0, v0=v0)


@dataclass(frozen=True)
class PlanOutcome:
    """What a stage returns to `run_plan`: the trajectory to write, the robot for the
    replay, the status and a summary text; for the stage after it,
    the problem it solved (`setup`), a discovery's `ContactResult` (`result`) or the exact
    re-solves' `ResolveChain` (`chain`: its plan's node file is written as `plan.npz`)."""

    trajectory: Trajectory | None
    robot: Robot | None
    status: str
    success: bool
    summary: str
    task: dict | None = None  # the goals measured (`TaskReport.to_dict()`), if stated
    result: ContactResult | None = None
    setup: PlanSetup | None = None
    chain: ResolveChain | None = None


@dataclass(frozen=True)
class StageInput:
    """What a stage of a plan's pipeline gets: the plan and task names, the staging
    folder, the user's settings, the outcome of the stage before (None first) and the
    seed of the discovery's first solve (0: its unperturbed guess; the k-th run of a
    plan with `Plan.whole_attempts` has seed k)."""

    plan: str
    task: str
    out: Path
    verbose: bool
    attempts: int | None
    previous: PlanOutcome | None
    seed: int = 0


class Stage(ABC):
    """One step of a plan's pipeline (`Plan.stages`), run in turn by `run_plan`; a stage
    whose `tasks` is a tuple runs only for those tasks of its plan (None: for all)."""

    name: str
    tasks: tuple[str, ...] | None = None

    @abstractmethod
    def run(self, given: StageInput) -> PlanOutcome:
        """The stage's outcome (the last stage's is written)."""

    @property
    def own_setup(self) -> bool:
        """Whether the stage solves a problem of its own rather than the stage before's."""
        return False

    @property
    def follows_start(self) -> bool:
        """Whether a sweep's case, which perturbs the discovery's start, can run this
        stage from that start (`at_start`): one that solves the stage before's problem,
        or one whose own problem is restated from it."""
        return not self.own_setup

    def at_start(self, q0: np.ndarray, v0: np.ndarray) -> Stage:
        """This stage as a sweep's case runs it from the start (q0, v0); default itself
        (it solves the problem of the stage before)."""
        return self

    def with_threads(self, threads: int) -> Stage:
        """This stage solving on `threads` threads (a sweep's case shares the cores with
        others); default: unchanged."""
        return self

    def solved_problem(self, problem: ContactProblem) -> ContactProblem:
        """The problem this stage solves of the plan's `problem` (a sweep's case solves
        it from its own start); default the problem itself."""
        return problem


@dataclass(frozen=True)
class Discover(Stage):
    """Find the contact sequence: the time-freezing homotopy (`solve_contact`, with the
    plan's attempts) on the problem `build(task)` states, verified, goals checked.

    `continue_sigma`: None, the homotopy starts from the problem's own guess; a number,
    a continuation: it starts from the discovery before this stage (its whole iterate,
    `solve_contact(initial_guess=...)`: the same robot and grid) with sigma_0 =
    `continue_sigma`, e.g. a walk up a step from the same walk found on flat ground.

    `path_rows`: the rows of the problem's path constraint the discovery keeps (None: all;
    `tfcontact.task.discovery_path_rows`); the outcome keeps the whole problem, so a stance
    re-solve after it chooses its own rows."""

    build: Callable[[str | None], PlanSetup]
    name: str = "discover"
    tasks: tuple[str, ...] | None = None
    continue_sigma: float | None = None
    path_rows: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.continue_sigma is not None and not (
                isinstance(self.continue_sigma, int | float)
                and np.isfinite(self.continue_sigma) and self.continue_sigma > 0):
            raise InvalidInput(f"`continue_sigma` must be a number > 0 or None, got "
                               f"{self.continue_sigma!r}")

    @property
    def own_setup(self) -> bool:
        # a continuation solves its own task, not the problem of the discovery before
        return self.continue_sigma is not None

    @property
    def follows_start(self) -> bool:
        return True

    def at_start(self, q0: np.ndarray, v0: np.ndarray) -> Stage:
        """A continuation with its own task stated from the start (q0, v0)
        (`PlanSetup.problem_from`: a task file's reference splines begin there), as a
        sweep's case states the discovery it continues."""
        if self.continue_sigma is None:
            return self
        build = self.build

        def from_start(task: str | None) -> PlanSetup:
            setup = build(task)
            return dataclasses.replace(setup, problem=setup.problem_from(q0, v0))

        return dataclasses.replace(self, build=from_start)

    def run(self, given: StageInput) -> PlanOutcome:
        from tfcontact.ocp.contact import solve_contact

        setup = self.build(given.task)
        robot, options = setup.robot, setup.options
        problem = self.solved_problem(setup.problem)
        if given.attempts is not None:
            options = dataclasses.replace(options, attempts=given.attempts)
        if given.verbose:
            print(f"plan {given.plan} ({given.task}): {robot.model.name}, nq = {robot.nq}, "
                  f"T = {problem.horizon} s, N = {problem.n_intervals}", flush=True)
        if self.continue_sigma is None:
            result = solve_contact(problem, options, first_seed=given.seed,
                                   verbose=given.verbose)
            return discovery_outcome(result, setup)
        before = discovered(given)
        if given.verbose:
            print(f"{self.name}: from the discovery before ({before.status}, objective "
                  f"{before.ocp.cost:.6g}), the homotopy from sigma = "
                  f"{self.continue_sigma:g}", flush=True)
        # the seed of a whole run perturbed the discovery before; this one starts from it
        result = solve_continued(problem, options, before, self.continue_sigma,
                                 verbose=given.verbose)
        return discovery_outcome(result, setup)

    def solved_problem(self, problem: ContactProblem) -> ContactProblem:
        """The plan's problem with only the path rows the discovery keeps (`path_rows`)."""
        return kept_path_rows(problem, self.path_rows)


def solve_continued(problem: ContactProblem, options: ContactSolverOptions,
                    before: ContactResult, sigma: float, *, verbose: bool = False
                    ) -> ContactResult:
    """A discovery continued from `before`, another task's plan on the same robot and
    grid (a task's `[continuation]`): its whole iterate the guess, the homotopy from
    sigma_0 = `sigma` (`Discover(continue_sigma=...)`)."""
    from tfcontact.ocp.contact import solve_contact

    options = dataclasses.replace(options, homotopy=dataclasses.replace(
        options.homotopy, sigma_0=sigma))
    return solve_contact(problem, options, initial_guess=before, verbose=verbose)


def run_stages(plan: str, task: str, stages: Sequence[Stage], out: Path, *,
               verbose: bool = False, attempts: int | None = None,
               outcome: PlanOutcome | None = None, seed: int = 0
               ) -> tuple[PlanOutcome, list[dict]]:
    """Run `stages` in turn, each given the outcome before it (`outcome` first: None when
    the first stage is a discovery; `seed`: its first solve's, `StageInput.seed`). Returns
    the last outcome and, per stage, its name, status, whether it ran, IPOPT iterations and
    seconds (a stage that did not start hands on the trajectory and status before it: not
    `ran`, 0 iterations of its own)."""
    times = []
    for stage in stages:
        if verbose and len(stages) > 1:
            print(f"plan {plan} ({task}): stage {stage.name}", flush=True)
        began, before = time.perf_counter(), outcome
        outcome = stage.run(StageInput(plan, task, out, verbose, attempts, outcome, seed))
        ran = outcome.trajectory is not None and (
            before is None or outcome.trajectory is not before.trajectory)
        times.append({"stage": stage.name, "status": outcome.status, "ran": ran,
                      "iterations": int(outcome.trajectory.solver.get("iterations", 0))
                      if ran else 0,
                      "seconds": time.perf_counter() - began})
    return outcome, times


def discovery_outcome(result: ContactResult, setup: PlanSetup) -> PlanOutcome:
    """What `Discover` returns for its `ContactResult` on `setup`'s problem (also what a
    sweep hands to a plan's later stages after solving a perturbed start)."""
    from tfcontact.plan_format import terrain_directions, trajectory_from_result

    directions = (None if setup.terrain is None
                  else terrain_directions(setup.robot, setup.terrain))
    trajectory = trajectory_from_result(result, setup.robot.spec, setup.scene,
                                        directions=directions, task=result.task.to_dict())
    return PlanOutcome(trajectory, setup.robot, result.status, result.success,
                       result.summary(), task=result.task.to_dict(), result=result,
                       setup=setup)


@dataclass(frozen=True)
class Start:
    """Where a chain of exact re-solves starts: its guess (a relaxed plan, (t, x, u) or
    None), the contact sequence to follow, the solves made on the way (`ChainStep`s) and
    how many of the chain's first levels they replace."""

    guess: ContactResult | tuple[np.ndarray, np.ndarray, np.ndarray] | None
    phases: tuple[Phase, ...]
    steps: tuple[ChainStep, ...] = ()
    skip_levels: int = 0


LIFT_OFFS_AT_CONTROL_JUMPS = PolishOptions(lift_offs_at_control_jumps=True,
                                           element_derivatives=True, threads=2,
                                           max_iter=1000)
"""The exact re-solve's default: `PolishOptions` with each lift-off straight from stick
moved to the nearest control jump, where the re-solve can model it, and each RK4 step
differentiated once (`element_derivatives`, on two threads; the monoped's chain and the
stance re-solve do the same): `tfcontact plan hopper-exact`'s re-solve took 94 s instead
of 295 s (building its NLP 8 s instead of 57 s), to the same objective and the same
verified plan (benchmarks/hopper_bench.md). IPOPT stops at 1000 iterations, and the
chain's last level is then solved once more from that iterate (`resolve_chain`): on the
AVX-512 EPYC hopper-exact's re-solve crept (objective 24.4 to 22.7 in 3000 iterations,
576 s), and its fresh restart converged in 348 more; capped at 1000, the restart
converged in 428 to the same plan, 298 s in all against 663 (benchmarks/hopper_bench.md)."""


class NoStart(Exception):  # noqa: N818 (a stage's verdict, not a program error)
    """A `ResolveStart` found nothing to follow; its message says why."""


class ResolveStart(ABC):
    """How an `ExactResolve` stage starts from the outcome before it (a strategy)."""

    @abstractmethod
    def begin(self, given: StageInput, levels: Sequence[ResolveLevel]) -> Start:
        """The chain's start. Raises `NoStart` when the outcome before gives none;
        `InvalidInput` when the stage before is of the wrong kind."""


def discovery_step(result: ContactResult) -> ChainStep:
    history = result.ocp.mpcc_result.history
    return ChainStep("time-freezing homotopy", history[-1].ipopt_status if history else "none",
                     result.ocp.total_iterations, float(result.timings.get("total", np.nan)),
                     float(result.ocp.cost),
                     result.status)


def discovered(given: StageInput) -> ContactResult:
    """The discovery before a stage (its `ContactResult`).

    Raises:
        InvalidInput: no discovery stage before it."""
    found = given.previous
    if found is None or found.result is None:
        raise InvalidInput("an exact re-solve needs a discovery stage before it "
                           "(Plan stages (Discover(...), ExactResolve()))")
    return found.result


@dataclass(frozen=True)
class FoundSequence(ResolveStart):
    """Follow the contact sequence the discovery found (`contact_phases` with `options`;
    default: lift-offs at the nearest control jump), its relaxed plan the guess."""

    options: PolishOptions | None = None

    def begin(self, given: StageInput, levels: Sequence[ResolveLevel]) -> Start:
        result = discovered(given)
        if not result.ocp.success:
            raise NoStart(f"the discovery's homotopy did not converge ({result.status})")
        options = self.options or LIFT_OFFS_AT_CONTROL_JUMPS
        return Start(result, contact_phases(result, options), (discovery_step(result),))


@dataclass(frozen=True)
class PreviousPlan(ResolveStart):
    """Go on from the exact re-solves before (a verified plan), along its sequence."""

    def begin(self, given: StageInput, levels: Sequence[ResolveLevel]) -> Start:
        chain = None if given.previous is None else given.previous.chain
        if chain is None:
            raise InvalidInput("this re-solve goes on from an exact re-solve before it")
        if not chain.success:
            raise NoStart(f"the plan before is not verified ({chain.status})")
        plan = chain.plan
        return Start((plan.t, plan.x, plan.u), plan.phases, chain.steps)


@dataclass(frozen=True)
class ExactResolve(Stage):
    """Re-solve the plan before exactly along a contact sequence (`tfcontact.ocp.chain`:
    the hybrid system's own modes, impacts at the found times, no time-freezing
    relaxation; level after level, each warm started from the last), verified against the
    exact-impact reference, the goals and path constraints checked at its nodes. One
    planar frictional contact (`polish` refuses others).

    Args:
        options: `PolishOptions` of the default single level; default: lift-offs at the
            nearest control jump.
        levels: the chain's levels for the stage's setup (default: one level, `options`).
        start: where the chain starts (default `FoundSequence`: the discovery's sequence).
        setup: the problem to re-solve for a task (default: the stage before's).
    """

    options: PolishOptions | None = None
    levels: Callable[[PlanSetup], Sequence[ResolveLevel]] | None = None
    start: ResolveStart | None = None
    setup: Callable[[str], PlanSetup] | None = None
    name: str = "exact re-solve"
    tasks: tuple[str, ...] | None = None

    @property
    def own_setup(self) -> bool:
        return self.setup is not None

    def run(self, given: StageInput) -> PlanOutcome:
        found = given.previous
        if found is None or found.setup is None:
            raise InvalidInput("an exact re-solve needs a discovery stage before it "
                               "(Plan stages (Discover(...), ExactResolve()))")
        start_with = self.start or FoundSequence(self.options)
        setup = self.setup(given.task) if self.setup else found.setup
        levels = (tuple(self.levels(setup)) if self.levels else (ResolveLevel(
            self.name, setup.problem, self.options or LIFT_OFFS_AT_CONTROL_JUMPS),))
        try:
            start = start_with.begin(given, levels)
        except NoStart as why:  # nothing to follow: the stage before is the outcome
            return dataclasses.replace(
                found, status=found.status if not found.success else "chain_failed",
                success=False, summary=f"{found.summary}\n{self.name} not started: {why}")
        chain = resolve_chain(levels[start.skip_levels:], start.phases, start.guess,
                              steps=start.steps, verbose=given.verbose)
        return resolved_outcome(chain, setup, found)


def resolved_outcome(chain: ResolveChain, setup: PlanSetup, found: PlanOutcome | None
                     ) -> PlanOutcome:
    """The outcome of a chain of exact re-solves: its trajectory (the plan's nodes as
    samples), the goals measured on it, the status and summary."""
    from tfcontact.plan_format.adapters import trajectory_from_polished

    discovery = ("" if found is None or found.result is None
                 else f"discovery: {found.result.status}\n")
    if chain.plan is None:
        return PlanOutcome(None, setup.robot, chain.status, False,
                           discovery + chain.summary(), setup=setup, chain=chain)
    plan, problem = chain.plan, chain.problem
    if np.any(np.diff(plan.t) < 0):
        # a failed NLP's iterate can move a switch past its neighbouring nodes: it has no
        # trajectory (its samples would run backwards in time); its nodes are still saved
        return PlanOutcome(None, setup.robot, chain.status, False,
                           f"{discovery}{chain.summary()}\nno trajectory written: the last "
                           "re-solve's node times decrease (an iterate, not a plan)",
                           setup=setup, chain=chain)
    task = _polished_task(plan, problem)
    status = chain.status if not chain.success else \
        ("converged" if task.passed else task.status)
    summary = f"{discovery}{chain.summary()}\n{task.summary()}"
    solver = {"status": status, "message": chain.message, "objective": plan.cost,
              "wall_time": chain.wall_time, "path_violation": chain.path_violation,
              "phases": [dataclasses.asdict(p) for p in plan.phases],
              "steps": [dataclasses.asdict(step) for step in chain.steps],
              "method": "exact re-solve along the contact sequence (tfcontact.ocp.polish): "
                        + ("Radau IIA collocation" if plan.integrator == "radau"
                           else "RK4 multiple shooting") + " on the fixed control grid",
              "steps_per_interval": list(plan.substeps)}
    trajectory = trajectory_from_polished(plan, problem.system.cls, setup.robot.spec,
                                          setup.scene, solver=solver, task=task.to_dict())
    return PlanOutcome(trajectory, setup.robot, status, chain.success and task.passed,
                       summary, task=task.to_dict(), setup=setup, chain=chain)


LIFT_OFF_MARGIN = 1e-3
"""[m] above a lift-off goal's height for the stance re-solve's swing rows, so that the
goal's check at the plan's nodes (gap >= height) holds after IPOPT's bound relaxation."""


def lift_off_heights(goals: Sequence[Goal], n_contacts: int) -> tuple[float | None, ...]:
    """`StanceOptions.swing_heights` from a problem's lift-off goals: each contact asked
    to lift off keeps its goal's height (plus `LIFT_OFF_MARGIN`) in the swings the
    discovery lifted it that high; the other contacts None."""
    heights: list[float | None] = [None] * n_contacts
    for goal in goals:
        if isinstance(goal, LiftOffs):
            heights[goal.contact] = max(heights[goal.contact] or 0.0,
                                        goal.height + LIFT_OFF_MARGIN)
    return tuple(heights) if any(h is not None for h in heights) else ()


@dataclass(frozen=True)
class StanceResolve(Stage):
    """Re-solve the discovery's plan exactly along the stances it found
    (`tfcontact.ocp.stances`: several contacts, each closed one sticking, touchdowns at
    free times with their impacts, lift-offs at control jumps), verified with the
    multi-contact reference, the goals checked at its nodes.

    Args:
        options: `StanceOptions` (default: its defaults); without `swing_heights` the
            problem's lift-off goals give them (`lift_off_heights`).
        path_rows: the rows of the problem's path constraint the re-solve keeps (None:
            all; (): none). A task file keeps its contacts' reach rows, a leg's range of
            motion (`tfcontact.task.resolve_path_rows`), and drops the rows that steer the
            discovery: no-slip (v_t^2 <= k gap), which every stance meets by construction
            (its closed contacts stick) and which, kept, made a two-legged step's re-solve
            wander for more than 2000 IPOPT iterations (about 270 without,
            benchmarks/legged.md), and clearance.
    """

    options: StanceOptions | None = None
    path_rows: tuple[int, ...] | None = None
    name: str = "stance re-solve"
    tasks: tuple[str, ...] | None = None

    def with_threads(self, threads: int) -> Stage:
        return dataclasses.replace(self, options=dataclasses.replace(
            self.options or StanceOptions(), threads=threads, blas_threads=threads))

    def run(self, given: StageInput) -> PlanOutcome:
        result = discovered(given)
        found = given.previous
        setup = found.setup
        options = self.options or StanceOptions()
        try:
            refusal = discovery_refusal(result, options)
            if refusal:
                raise NoStart(refusal)
            stances = schedule_of(result, options)
        except (NoStart, InvalidInput) as why:
            if given.verbose:
                print(f"{self.name} not started: {why}", flush=True)
            return dataclasses.replace(
                found, status=found.status if not found.success else "chain_failed",
                success=False, summary=f"{found.summary}\n{self.name} not started: {why}")
        if given.verbose and not result.ocp.success:
            print(f"{self.name}: the discovery stopped short ({result.status}); its last "
                  f"solved NLP (complementarity residual {result.ocp.residual:.2g} <= "
                  f"{options.discovery_residual:g}) proposes the stances", flush=True)
        if given.verbose:
            print(f"{self.name}: {len(stances)} stances, closed contacts "
                  + ", ".join(f"{list(s.closed)} from {s.start:.3f} s" for s in stances),
                  flush=True)
        problem = setup.problem
        options = with_lift_off_heights(options, problem)
        plan = resolve_stances(kept_path_rows(problem, self.path_rows), stances, options,
                               guess=result, verbose=given.verbose)
        return stance_outcome(plan, setup, options, discovery=result)


def discovery_refusal(result: ContactResult, options: StanceOptions) -> str | None:
    """Why the stance re-solve does not follow `result`'s stances, or None when it does:
    a converged discovery, or one stopped short whose last solved NLP's complementarity
    residual is within `options.discovery_residual`."""
    limit, residual = options.discovery_residual, result.ocp.residual
    if result.ocp.success or (limit is not None and residual <= limit):
        return None
    stopped = f"the discovery's homotopy did not converge ({result.status})"
    if limit is None:
        return f"{stopped}; `discovery_residual` lets the re-solve follow its last solved NLP"
    return (f"{stopped} and its last solved NLP's complementarity residual {residual:.2g} "
            f"exceeds `discovery_residual` = {limit:g}")


def with_lift_off_heights(options: StanceOptions, problem: ContactProblem) -> StanceOptions:
    """`options`, its `swing_heights` from the problem's lift-off goals where it has none
    (`lift_off_heights`)."""
    if options.swing_heights:
        return options
    return dataclasses.replace(options, swing_heights=lift_off_heights(
        problem.goals, problem.system.cls.n_contacts))


def kept_path_rows(problem: ContactProblem, rows: tuple[int, ...] | None) -> ContactProblem:
    """`problem` with only the path rows `rows` (None: all)."""
    return problem if rows is None or problem.path is None else (
        dataclasses.replace(problem, path=problem.path.rows(rows)))


def stance_outcome(plan: StancePlan, setup: PlanSetup, options: StanceOptions,
                   discovery: ContactResult | None = None) -> PlanOutcome:
    """The outcome of a plan solved along stances: its trajectory, the goals measured at
    its nodes, the status and summary (`discovery`: the relaxed plan whose stances it
    followed, None for a sequence given as data)."""
    from tfcontact.ocp.goals import Motion, check_goals
    from tfcontact.plan_format import terrain_directions, trajectory_from_stances

    problem = setup.problem
    cls = problem.system.cls
    gaps = np.asarray(cls.function("gaps")(plan.x[:, :cls.n_q].T)).T
    task = check_goals(problem.goals, Motion(t=plan.t, q=plan.x[:, :cls.n_q],
                                             gaps=gaps.reshape(len(plan.t), -1),
                                             names=cls.q_names))
    status = plan.status if not plan.success else (
        "converged" if task.passed else task.status)
    found = ("the contact sequence given" if discovery is None
             else f"discovery: {discovery.status}")
    summary = f"{found}\n{plan.summary()}\n{task.summary()}"
    solver = {"status": status, "objective": plan.cost, "wall_time": plan.solve_time,
              "ipopt_status": plan.ipopt_status, "iterations": plan.iterations,
              "stances": [dataclasses.asdict(s) for s in plan.stances],
              "timing": None if plan.timing is None else dataclasses.asdict(plan.timing),
              "method": ("exact re-solve" if discovery is not None else "exact solve")
                        + " along the stances (tfcontact.ocp.stances): "
                        + ("Radau IIA collocation" if options.integrator == "radau"
                           else "RK4 multiple shooting")
                        + (", inverse-dynamics form" if options.inverse_dynamics else "")
                        + (", contact forces lifted" if options.lifted_forces else "")
                        + (f", IPOPT's {options.barrier} barrier"
                           if options.barrier != "monotone" else "")
                        + " on the fixed control grid"}
    if discovery is not None:
        solver["discovery"] = {"status": discovery.status, "objective": discovery.ocp.cost,
                               "iterations": discovery.ocp.total_iterations}
    directions = (None if setup.terrain is None
                  else terrain_directions(setup.robot, setup.terrain))
    trajectory = trajectory_from_stances(plan, cls, setup.robot.spec, setup.scene,
                                         directions=directions, solver=solver,
                                         task=task.to_dict())
    return PlanOutcome(trajectory, setup.robot, status, plan.success and task.passed,
                       summary, task=task.to_dict(), setup=setup)


@dataclass(frozen=True)
class GivenStances(Stage):
    """Solve a plan with contacts exactly along a contact sequence given as data (no
    discovery; `tfcontact.ocp.stances`: each closed contact sticking, touchdowns at free
    times inside their control intervals with their impacts, lift-offs at control jumps),
    verified with the multi-contact reference, the goals checked at its nodes.

    The guess: the problem's own (`ContactProblem.guess`, e.g. a task's reference; else
    the start state everywhere) at the control jumps, its control guess (else zero).

    Args:
        build: the setup of a task (as `Discover`'s).
        stances: the sequence (`tfcontact.ocp.stances.Stance`s; `tfcontact.task.task_stances`).
        options: `StanceOptions` (default: its defaults); without `swing_heights` the
            problem's lift-off goals give them (`lift_off_heights`).
        path_rows: as `StanceResolve`'s.
    """

    build: Callable[[str | None], PlanSetup]
    stances: tuple[Stance, ...]
    options: StanceOptions | None = None
    path_rows: tuple[int, ...] | None = None
    name: str = "stance solve"
    tasks: tuple[str, ...] | None = None

    @property
    def own_setup(self) -> bool:
        return True

    def with_threads(self, threads: int) -> Stage:
        return dataclasses.replace(self, options=dataclasses.replace(
            self.options or StanceOptions(), threads=threads, blas_threads=threads))

    def run(self, given: StageInput) -> PlanOutcome:
        setup = self.build(given.task)
        problem = setup.problem
        n_q, n_u = problem.system.cls.n_q, problem.system.cls.n_u
        n_int = problem.n_intervals
        if given.verbose:
            print(f"plan {given.plan} ({given.task}): {setup.robot.model.name}, nq = "
                  f"{setup.robot.nq}, T = {problem.horizon} s, N = {n_int}, "
                  f"{len(self.stances)} stances given", flush=True)
        start = np.concatenate([problem.q0, problem.v0])
        states = (np.tile(start, (n_int + 1, 1)) if problem.guess is None
                  else np.asarray(problem.guess, dtype=float).reshape(n_int + 1, 2 * n_q))
        controls = (np.zeros((n_int, n_u)) if problem.control_guess is None
                    else np.broadcast_to(np.asarray(problem.control_guess, dtype=float),
                                         (n_int, n_u)).copy())
        options = with_lift_off_heights(self.options or StanceOptions(), problem)
        guess = (np.linspace(0.0, problem.horizon, n_int + 1), states, controls)
        plan = resolve_stances(kept_path_rows(problem, self.path_rows), self.stances,
                               options, guess=guess, verbose=given.verbose)
        return stance_outcome(plan, setup, options)


@dataclass(frozen=True)
class Plan:
    """A named robot plan as data: its tasks and the stages `run_plan` runs in turn (e.g.
    discover the contact sequence, then re-solve exactly along it).

    `whole_attempts`: None, a failed plan is solved again by its discovery alone
    (`ContactSolverOptions.attempts`, judged on the discovery's own plan); an integer n,
    the whole pipeline runs up to n times until its last stage's plan succeeds (verified,
    task done, clear of the terrain), the k-th run's discovery one solve from its guess
    perturbed with seed k (`StageInput.seed`). A discovery's relaxed plan that a later
    stage re-solves exactly is not the plan, so its own verdict cannot decide a retry:
    bolt's relaxed walks all fail the reference that their exact re-solves pass."""

    name: str
    summary: str
    tasks: tuple[str, ...]
    stages: tuple[Stage, ...]
    whole_attempts: int | None = None

    def __post_init__(self) -> None:
        if not self.stages or not all(isinstance(s, Stage) for s in self.stages):
            raise InvalidInput(f"plan `{self.name}` needs stages (Discover, ExactResolve, "
                               "...)")
        first = self.stages[0]
        if isinstance(first, Discover) and first.continue_sigma is not None:
            raise InvalidInput(f"plan `{self.name}`: its first stage continues a discovery "
                               "before it (`continue_sigma`); put that discovery first")
        if self.whole_attempts is not None:
            object.__setattr__(self, "whole_attempts",
                               positive_int(self.whole_attempts, "whole_attempts"))
            if not isinstance(self.stages[0], Discover):
                raise InvalidInput(f"plan `{self.name}`: `whole_attempts` needs a Discover "
                                   "first (its seed is what changes between runs)")
        for stage in self.stages:
            unknown = set(stage.tasks or ()) - set(self.tasks)
            if unknown:
                raise InvalidInput(f"plan `{self.name}`: stage `{stage.name}` names tasks "
                                   f"{sorted(unknown)} the plan does not have ({self.tasks})")

    @property
    def build(self) -> Callable[[str | None], PlanSetup] | None:
        """The problem builder of a plan that starts with a `Discover` or `GivenStances`
        (sweeps perturb its start), else None."""
        first = self.stages[0]
        return first.build if isinstance(first, Discover | GivenStances) else None

    @property
    def given_sequence(self) -> GivenStances | None:
        """The first stage when it solves along a contact sequence given as data (no
        discovery), else None."""
        first = self.stages[0]
        return first if isinstance(first, GivenStances) else None

    def stages_for(self, task: str) -> tuple[Stage, ...]:
        """The stages that run for `task`, in order."""
        return tuple(s for s in self.stages if s.tasks is None or task in s.tasks)


def _polished_task(plan: PolishedPlan, problem: ContactProblem) -> TaskReport:
    """The problem's goals measured on an exact re-solve's nodes (`TaskReport`)."""
    from tfcontact.ocp.goals import Motion, check_goals
    from tfcontact.ocp.polish import node_samples

    cls = problem.system.cls
    gaps = node_samples(plan, cls)["gap"].reshape(len(plan.t), -1)
    motion = Motion(t=np.asarray(plan.t), q=np.asarray(plan.x)[:, :cls.n_q], gaps=gaps,
                    names=cls.q_names)
    return check_goals(problem.goals, motion)
