"""How a sweep builds a plan for one case: one `SweepTarget` object per plan."""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.scenes import PLANS, PlanSetup, plan_named
from tfcontact.sweep.perturbation import (
    CoordinateRange,
    Perturbation,
    PerturbedStart,
    perturbed_problem,
)

if TYPE_CHECKING:
    from tfcontact.scenes import Plan
    from tfcontact.scenes.pipeline import GivenStances, Stage


class SweepTarget(ABC):
    """A plan as a sweep sees it: its tasks, the problem-level grid keys it can vary
    (`tfcontact.sweep.GRID_PARAMETERS` of level "problem") and its start perturbation.

    Targets are built on the workers, so they must pickle (module-level frozen dataclasses).
    """

    name: str
    tasks: tuple[str, ...]
    problem_parameters: frozenset[str]

    @abstractmethod
    def setup(self, task: str, params: Mapping[str, float]) -> PlanSetup:
        """The plan's robot, problem and options for `task` with the problem-level `params`."""

    def perturbation(self, setup: PlanSetup) -> Perturbation:
        """The start perturbation (default: `Perturbation.from_names` of the coordinates)."""
        return Perturbation.from_names(tuple(setup.problem.system.cls.q_names))

    def from_start(self, setup: PlanSetup, task: str, params: Mapping[str, float],
                   start: PerturbedStart):
        """The `ContactProblem` solved from `start` (default: the plan's problem with only
        its start state replaced)."""
        return perturbed_problem(setup.problem, start)

    def description(self) -> dict:
        """What else defines this target's cases, for the sweep file (a resumed sweep must
        match it); default none."""
        return {}

    def later_stages(self, task: str) -> tuple[Stage, ...]:
        """The plan's stages after its discovery that a case runs on the discovery's
        outcome, as `tfcontact plan` would (default none: the discovery is the plan)."""
        return ()

    def whole_attempts(self, task: str) -> int | None:
        """How often a case runs the whole plan until it succeeds (`Plan.whole_attempts`;
        default None: once, the discovery retried by its own attempts)."""
        return None

    def given_sequence(self, task: str) -> GivenStances | None:
        """The plan's first stage when it solves along a contact sequence given as data
        instead of a discovery (a case runs it on its perturbed start), else None."""
        return None

    def discovery_problem(self, task: str, problem: Any) -> Any:
        """The problem a case's discovery solves of its `ContactProblem` (default: all of
        it)."""
        return problem


HOPPER_PERTURBATION = Perturbation((
    CoordinateRange("x", -0.05, 0.05),
    CoordinateRange("z", 0.0, 0.05),
    CoordinateRange("pitch", -0.05, 0.05),
))
"""The hopper's perturbed starts: base x +-5 cm, base height up to 5 cm higher (the foot
rests on the ground at the nominal start, gap z - l cos(pitch) = 0, so it only rises),
leg angle +-0.05 rad."""


def _check_task(target: SweepTarget, task: str) -> None:
    if task not in target.tasks:
        raise InvalidInput(f"plan `{target.name}` has no task `{task}`; tasks: "
                           f"{', '.join(target.tasks)}")


@dataclass(frozen=True)
class HopperTarget(SweepTarget):
    """The hopper plan (`tfcontact.scenes.hopper`, TF-8): the plan's problem and options
    (`hopper_problem`, `hopper_options`), its friction coefficient and a_n set in its
    `HopperTask`. Tasks: `hopper_task`'s ("short" as `tfcontact plan hopper`).

    `reference_from_start`: a perturbed start's task tracks a reference spline that begins
    at that start (`HopperTask.starting_at`), as a user planning from where the robot
    stands would set it; False keeps the spline's first way point, pulling the start back
    to it (the first sweep, benchmarks/sweeps/hopper: every start moved more than 3 cm
    ahead of it failed).
    """

    name: str = "hopper"
    tasks: tuple[str, ...] = ("short", "long", "bench")
    problem_parameters: frozenset[str] = frozenset({"friction", "a_n"})
    start_perturbation: Perturbation = field(default=HOPPER_PERTURBATION)
    reference_from_start: bool = True

    def setup(self, task: str, params: Mapping[str, float]) -> PlanSetup:
        from tfcontact.scenes.hopper import hopper_options, hopper_problem

        robot, ground, problem = hopper_problem(self._task(task, params))
        options = hopper_options(self._task(task, params))
        scene = {"terrain": {"type": "flat", "height": float(ground.height),
                             "normal": [float(c) for c in ground.normal]}}
        return PlanSetup(robot, problem, options, scene)

    def perturbation(self, setup: PlanSetup) -> Perturbation:
        return self.start_perturbation

    def from_start(self, setup: PlanSetup, task: str, params: Mapping[str, float],
                   start: PerturbedStart):
        if not self.reference_from_start:
            return perturbed_problem(setup.problem, start)
        from tfcontact.scenes.hopper import hopper_problem

        data = self._task(task, params).starting_at(np.concatenate([start.q0, start.v0]))
        return hopper_problem(data)[2]

    def description(self) -> dict:
        return {"reference": "from the start" if self.reference_from_start
                else "the task's first way point"}

    def _task(self, task: str, params: Mapping[str, float]):
        from tfcontact.scenes.hopper import hopper_task

        _check_task(self, task)
        changes = {"mu": params.get("friction"), "a_n": params.get("a_n")}
        return dataclasses.replace(hopper_task(task),
                                   **{k: v for k, v in changes.items() if v is not None})


PARTICLE_PERTURBATION = Perturbation((
    CoordinateRange("q_x", -0.05, 0.05),
    CoordinateRange("q_z", 0.0, 0.05),
))
"""The particle's perturbed starts: x +-5 cm, drop height up to 5 cm higher [m]."""


@dataclass(frozen=True)
class ParticleTarget(SweepTarget):
    """TF-3, the particle with friction pushed to x = 3 m (`particle_friction_problem`),
    with the options its CI test solves it with (Radau IIA 2, N_FE = 3, l_inf penalty,
    3 attempts); the friction coefficient and the auxiliary gain a_n vary. Tasks: "tf3"
    (N = 20) and "reduced" (N = 6, about 1 s a solve: the cheap sweep for CI and for
    trying a cluster)."""

    name: str = "particle"
    tasks: tuple[str, ...] = ("tf3", "reduced")
    problem_parameters: frozenset[str] = frozenset({"friction", "a_n"})
    start_perturbation: Perturbation = field(default=PARTICLE_PERTURBATION)

    def setup(self, task: str, params: Mapping[str, float]) -> PlanSetup:
        from tfcontact.fesd import RadauIIA
        from tfcontact.mpcc import LinfPenalty
        from tfcontact.ocp.contact import ContactSolverOptions
        from tfcontact.scenes.particle_ocps import BALL_GROUND, particle_friction_problem

        _check_task(self, task)
        data = {name: params[key] for key, name in (("friction", "mu"), ("a_n", "a_n"))
                if key in params}
        problem = particle_friction_problem(n_intervals=20 if task == "tf3" else 6, **data)
        options = ContactSolverOptions(scheme=RadauIIA(2), n_finite_elements=3,
                                       relaxation=LinfPenalty(), attempts=3)
        return PlanSetup(None, problem, options, BALL_GROUND)

    def perturbation(self, setup: PlanSetup) -> Perturbation:
        return self.start_perturbation


@dataclass(frozen=True)
class PlanTarget(SweepTarget):
    """Any plan of `tfcontact.scenes.PLANS` (or task file) that starts with a discovery or
    solves along a contact sequence given as data:
    its starts perturbed by its task's `start_ranges` or else the defaults of its
    coordinate names, only options-level grid keys; a case runs the plan's later stages
    too (e.g. biped-walk's stance re-solve)."""

    name: str
    tasks: tuple[str, ...]
    problem_parameters: frozenset[str] = frozenset()

    def setup(self, task: str, params: Mapping[str, float]) -> PlanSetup:
        _check_task(self, task)
        if params:
            raise InvalidInput(f"plan `{self.name}` has no problem-level grid keys, got "
                               f"{sorted(params)}")
        return plan_named(self.name).build(task)

    def later_stages(self, task: str) -> tuple[Stage, ...]:
        return plan_named(self.name).stages_for(task)[1:]

    def whole_attempts(self, task: str) -> int | None:
        return plan_named(self.name).whole_attempts

    def given_sequence(self, task: str) -> GivenStances | None:
        return plan_named(self.name).given_sequence

    def discovery_problem(self, task: str, problem: Any) -> Any:
        # as the plan's discovery stage states it: without the rows only its stance
        # re-solve keeps (`[[bodies]] discovery = false`), which the case's later stages
        # take from the whole problem
        return plan_named(self.name).stages_for(task)[0].solved_problem(problem)

    def description(self) -> dict:
        from tfcontact.scenes.plans import PLANS

        # a task file's case is the task stated from its start (`from_start`)
        return {} if self.name in PLANS else {"reference": "from the start"}

    def from_start(self, setup: PlanSetup, task: str, params: Mapping[str, float],
                   start: PerturbedStart):
        """The plan from `start` as its user would state it (`PlanSetup.from_start`: a
        task file's reference splines begin there, as the hopper's do), else only its
        start state replaced."""
        return setup.problem_from(start.q0, start.v0)

    def perturbation(self, setup: PlanSetup) -> Perturbation:
        if setup.start_ranges:
            return Perturbation(tuple(CoordinateRange(name, low, high)
                                      for name, (low, high) in setup.start_ranges.items()))
        return super().perturbation(setup)


SWEEP_TARGETS: dict[str, SweepTarget] = {"hopper": HopperTarget(),
                                         "particle": ParticleTarget()}
"""Plans with their own sweep target (and the TF-3 particle, a reference problem rather
than a `tfcontact plan`); other plans with a `build` get a `PlanTarget`."""


def sweep_target(plan: str) -> SweepTarget:
    """The `SweepTarget` of the plan named `plan`."""
    if plan in SWEEP_TARGETS:
        return SWEEP_TARGETS[plan]
    # a case perturbs the discovery's start, and every later stage must solve from the
    # outcome before it, not a problem of its own
    sweepable = sorted({*SWEEP_TARGETS, *(n for n, p in PLANS.items() if _sweepable(p))})
    if plan in PLANS:
        found = PLANS[plan]
    else:
        try:
            found = plan_named(plan)  # a task file or a shipped task
        except InvalidInput:
            if Path(plan).is_file():
                raise  # the task file's own error names its field
            raise InvalidInput(f"unknown plan `{plan}`; sweepable plans: "
                               f"{', '.join(sweepable)}, or a task file PATH.toml") from None
    if found.build is None:
        raise InvalidInput(f"plan `{plan}` does not start with a discovery or a contact "
                           f"sequence given as data, so it has no single contact problem "
                           f"whose start a sweep could perturb; sweepable plans: "
                           f"{', '.join(sweepable)}")
    # a given sequence's stage builds its problem, which a case replaces by its own
    own = [s.name for s in found.stages[1:] if not s.follows_start]
    if own:
        raise InvalidInput(f"plan `{plan}` has stages that solve problems of their own "
                           f"({', '.join(own)}), not the perturbed start's; sweepable "
                           f"plans: {', '.join(sweepable)}")
    return PlanTarget(plan, found.tasks)


def _sweepable(plan: Plan) -> bool:
    return plan.build is not None and all(s.follows_start for s in plan.stages[1:])
