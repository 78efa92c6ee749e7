"""Chains of exact re-solves: `polish_contact` level after level, each warm started from
the last (a coarse mesh first, then finer ones, then another integrator).

The re-solves are fragile (benchmarks/monoped_settings.md): one rerun of the monoped's
chain found another local solution and stopped at IPOPT's iteration cap in its second
level, and the next level from that capped iterate converged and passed. So a level that
stops at the cap hands its iterate to the next (`ChainStep.status` says so), and the last
level is solved once more from its own iterate if it stops at the cap; any other failure
ends the chain with a failed status. Only the last level's verification decides, together
with the problem's path constraints measured at every node of its plan
(`path_violation`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from tfcontact.errors import InvalidInput
from tfcontact.native import peak_memory, reset_peak_memory, return_memory
from tfcontact.ocp.contact import ContactProblem, ContactResult
from tfcontact.ocp.nodes import CAPPED, NlpTiming, bound_violation, system_states
from tfcontact.ocp.polish import (
    Phase,
    PolishedPlan,
    PolishOptions,
    node_samples,
    polish_contact,
    refined_substeps,
)

PATH_TOLERANCE = 1e-6
"""A plan whose path constraints are violated by more than this at a node fails."""


@dataclass(frozen=True)
class ResolveLevel:
    """One level of a chain: its name, the problem it re-solves and its `PolishOptions`,
    or a function (last level's plan or None, problem) -> `PolishOptions` for settings that
    depend on the last plan (a mesh refined by its local defects: `refine_by_defects`)."""

    name: str
    problem: ContactProblem
    options: PolishOptions | Callable[[PolishedPlan | None, ContactProblem], PolishOptions]

    def __post_init__(self) -> None:
        if not isinstance(self.problem, ContactProblem):
            raise InvalidInput(f"level `{self.name}` needs a ContactProblem, got "
                               f"{type(self.problem).__name__}")
        if not (isinstance(self.options, PolishOptions) or callable(self.options)):
            raise InvalidInput(f"level `{self.name}` needs PolishOptions or a function of the "
                               f"last plan, got {type(self.options).__name__}")


@dataclass(frozen=True)
class ChainStep:
    """One solve of a chain: its name, IPOPT status, iterations, seconds, objective and
    the plan's status; where known, where its time went and the NLP's size (`timing`) and
    the process's peak memory during it [GB]."""

    name: str
    ipopt_status: str
    iterations: int
    seconds: float
    objective: float
    status: str
    timing: NlpTiming | None = None
    peak_memory: float | None = None

    @classmethod
    def of(cls, name: str, plan: PolishedPlan, seconds: float,
           peak_memory: float | None = None) -> ChainStep:
        return cls(name, plan.ipopt_status, plan.iterations, seconds, plan.cost, plan.status,
                   plan.timing, peak_memory)

    def where_the_time_went(self) -> str:
        """"; " and the step's timing and peak memory, or "" if not known."""
        memory = "" if self.peak_memory is None else f", peak {self.peak_memory:.2f} GB"
        return "" if self.timing is None else f"; {self.timing.summary()}{memory}"


@dataclass(frozen=True, eq=False)
class ResolveChain:
    """What a chain of re-solves gave.

    Attributes:
        plan: the last solve's `PolishedPlan` (its verification decides), or None when the
            chain could not start.
        problem: the last level's `ContactProblem`.
        steps: every solve, in order (with the stages before the chain, if given).
        path_violation: the largest violation of the problem's path constraints at the
            plan's nodes (`path_violation`; NaN without a plan; the terminal constraint is
            the plan's verification's).
        wall_time: seconds for the chain.
        message: why the chain stopped, when it failed.
    """

    plan: PolishedPlan | None
    problem: ContactProblem
    steps: tuple[ChainStep, ...]
    path_violation: float
    wall_time: float
    message: str = ""

    @property
    def status(self) -> str:
        if self.plan is None:
            return "chain_failed"
        if self.plan.success and not self.path_violation <= PATH_TOLERANCE:
            return "verification_failed"  # between or at nodes, outside its path constraints
        return self.plan.status

    @property
    def success(self) -> bool:
        return self.status == "converged"

    def summary(self) -> str:
        lines = [f"exact re-solves: {self.status} in {self.wall_time:.0f} s"
                 + (f" ({self.message})" if self.message else "")]
        for step in self.steps:
            lines.append(f"  {step.name}: {step.status} (IPOPT {step.ipopt_status}, "
                         f"{step.iterations} iterations, {step.seconds:.0f} s, objective "
                         f"{step.objective:.6g}{step.where_the_time_went()})")
        if self.plan is not None:
            lines.append(self.plan.summary())
            lines.append(f"path constraints: largest violation at the nodes "
                         f"{self.path_violation:.3g} (tolerance {PATH_TOLERANCE:g})")
        return "\n".join(lines)


def path_violation(problem: ContactProblem, plan: PolishedPlan) -> float:
    """The largest violation of `problem.path` at the plan's nodes, each with the control
    that drives it (`node_samples`); 0 without path constraints. A Radau plan's nodes are
    its stage points; an RK4 plan's are its shooting nodes, not its inner steps. (The
    terminal constraint is checked by the plan's verification, `polish.terminal_violation`.)"""
    path = problem.path
    if path is None or path.expression.numel() == 0:
        return 0.0
    system = problem.system
    y = system_states(system, plan.x, plan.t)
    u = node_samples(plan, system.cls)["u"]
    values = np.asarray(ca.Function("path", [system.y, system.u], [path.expression])
                        .map(len(plan.t))(y.T, u.T)).T
    return bound_violation(values, path.lower, path.upper)


def resolve_chain(levels: Sequence[ResolveLevel], phases: tuple[Phase, ...],
                  guess: ContactResult | tuple[np.ndarray, np.ndarray, np.ndarray] | None, *,
                  steps: Sequence[ChainStep] = (), verbose: bool = True) -> ResolveChain:
    """Re-solve `levels` in order, each from the last (the first from `guess`: a relaxed
    plan, (t, x, u) or None), along `phases` as each level moves its switches; a level at
    the iteration cap hands its iterate on, the last is solved once more from its own
    iterate; any other failure stops the chain (module docstring). `steps`: the solves
    before the chain (a discovery, a search), kept in front of its own.

    Raises:
        InvalidInput: no levels.
    """
    if not levels:
        raise InvalidInput("a chain of re-solves needs at least one level")
    begin_chain = time.perf_counter()
    steps = list(steps)
    plan = solved_with = None
    for i, level in enumerate(levels):
        last = i == len(levels) - 1
        options = level.options
        if not isinstance(options, PolishOptions):  # settings from the last plan
            options = options(plan, level.problem)
        if (plan is not None and plan.success
                and solved_with == _nlp_of(level.problem, options)):
            # e.g. a mesh refined where no local defect exceeds its share: the same NLP
            # again, from its own solution
            if verbose:
                print(f"exact re-solve: {level.name}: the last plan is this level's "
                      "(same problem and options), verified; not solved again", flush=True)
            continue
        solved_with = _nlp_of(level.problem, options)
        for attempt in range(2 if last else 1):
            label = level.name if attempt == 0 else f"{level.name}, again from its capped iterate"
            if verbose:
                print(f"exact re-solve: {label}", flush=True)
            begin = time.perf_counter()
            reset_peak_memory()
            plan = polish_contact(level.problem, phases, options, guess=guess, verbose=verbose)
            steps.append(ChainStep.of(label, plan, time.perf_counter() - begin, peak_memory()))
            return_memory()
            guess, phases = (plan.t, plan.x, plan.u), plan.phases
            if plan.ipopt_status != CAPPED:
                break
        if not plan.solved and plan.ipopt_status != CAPPED:
            return ResolveChain(plan, level.problem, tuple(steps),
                                path_violation(level.problem, plan),
                                time.perf_counter() - begin_chain,
                                message=f"{level.name}: IPOPT {plan.ipopt_status}")
        if not plan.solved and verbose and not last:
            print(f"exact re-solve: {level.name} stopped at the iteration cap; its iterate "
                  "starts the next level", flush=True)
    problem = levels[-1].problem
    return ResolveChain(plan, problem, tuple(steps), path_violation(problem, plan),
                        time.perf_counter() - begin_chain,
                        message="" if plan.solved else f"{levels[-1].name}: IPOPT "
                                                       f"{plan.ipopt_status}")


def _nlp_of(problem: ContactProblem, options: PolishOptions) -> tuple:
    """What decides a level's NLP: its problem (by identity) and options, the mesh per
    interval spelled out (12 and (12,) * N are the same mesh)."""
    mesh = options.substeps_per_interval(problem.n_intervals)
    return id(problem), dataclasses.replace(options, substeps=mesh)


def refine_by_defects(base: PolishOptions, default_substeps: int
                      ) -> Callable[[PolishedPlan | None, ContactProblem], PolishOptions]:
    """Level options on the last plan's mesh (`default_substeps` per interval if it has
    none), its elements doubled in each interval whose local defect exceeds its share of
    the verification's tolerance (`refined_substeps`); the rest of `base` as it is."""

    def options(plan: PolishedPlan | None, problem: ContactProblem) -> PolishOptions:
        if plan is None:
            raise InvalidInput("a mesh refined by the local defects needs a level before it")
        mesh = plan.substeps if plan.substeps else (default_substeps,) * problem.n_intervals
        substeps = refined_substeps(mesh, plan.verification.local_defects,
                                    base.end_state_tolerance)
        return dataclasses.replace(base, substeps=substeps)

    return options
