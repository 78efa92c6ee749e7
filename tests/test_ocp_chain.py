"""Chains of exact re-solves (tfcontact.ocp.chain): the continuation past an iteration
cap, a failure that stops the chain, level options from the last plan, and the path
constraints measured at the plan's nodes. The solves are stand-ins; the real chains run in
tests/test_monoped_exact.py."""

from __future__ import annotations

import dataclasses
import types

import numpy as np
import pytest
from stand_in_plans import saved_plan, stand_in_plan

import tfcontact.ocp.chain as chain_module
from tfcontact.errors import InvalidInput
from tfcontact.ocp.chain import (
    PATH_TOLERANCE,
    ResolveChain,
    ResolveLevel,
    path_violation,
    refine_by_defects,
    resolve_chain,
)
from tfcontact.ocp.polish import STICK, Phase, PolishOptions
from tfcontact.scenes.monoped import REDUCED_TASK, monoped_problem
from tfcontact.scenes.monoped_exact import EXACT_TASK


@pytest.fixture(scope="module")
def reduced():
    return monoped_problem(REDUCED_TASK).problem


@pytest.fixture
def stand_ins(monkeypatch):
    """Replace the re-solve by `solves` (a list of functions) and the path measure by 0."""
    calls = []

    def install(fake):
        def polish(problem, phases, options, *, guess, verbose):
            calls.append((guess, options))
            return fake(options)

        monkeypatch.setattr(chain_module, "polish_contact", polish)
        monkeypatch.setattr(chain_module, "path_violation", lambda problem, plan: 0.0)
        return calls

    return install


def test_a_capped_level_hands_its_iterate_on_and_the_last_is_solved_again(reduced, stand_ins):
    """Level 1 stops at the iteration cap: level 2 starts from its iterate. Level 2 stops
    at the cap too: it is solved once more from its own iterate, and that decides."""
    outcomes = iter([("Maximum_Iterations_Exceeded", 1.0), ("Maximum_Iterations_Exceeded", 2.0),
                     ("Solve_Succeeded", 3.0)])

    def fake(options):
        status, cost = next(outcomes)
        return stand_in_plan(status, cost, shift=cost)

    calls = stand_ins(fake)
    levels = [ResolveLevel("first", reduced, PolishOptions()),
              ResolveLevel("second", reduced, PolishOptions())]
    result = resolve_chain(levels, (Phase(STICK, 0, 1),), None, verbose=False)
    guesses = [None if g is None else float(g[1][0, 0]) for g, _ in calls]
    assert guesses == [None, 1.0, 2.0]  # each solve starts from the last iterate
    assert [s.name for s in result.steps] == ["first", "second",
                                              "second, again from its capped iterate"]
    assert result.plan.cost == 3.0 and result.status == "converged" and not result.message


def test_any_other_failure_stops_the_chain(reduced, stand_ins):
    calls = stand_ins(lambda options: stand_in_plan("Infeasible_Problem_Detected", 1.0))
    levels = [ResolveLevel("first", reduced, PolishOptions()),
              ResolveLevel("second", reduced, PolishOptions())]
    result = resolve_chain(levels, (Phase(STICK, 0, 1),), None, verbose=False)
    assert len(calls) == 1 and result.status == "nlp_failed" and not result.success
    assert "first: IPOPT Infeasible_Problem_Detected" in result.summary()


def test_a_level_may_set_its_options_from_the_laststand_in_plan(reduced, stand_ins):
    """A mesh refined by the local defects: the second level doubles the first's 12
    elements where its local defects exceed 0.05 / 10 (intervals 3 and 7 here; 7 could
    not be replayed)."""
    defects = [1e-4] * 10
    defects[3], defects[7] = 0.03, float("nan")

    def fake(options):
        plan = stand_in_plan("Solve_Succeeded", 1.0, verification=types.SimpleNamespace(
            passed=True, summary=str, local_defects=tuple(defects)))
        return dataclasses.replace(plan, integrator=options.integrator,
                                   substeps=options.substeps_per_interval(10))

    calls = stand_ins(fake)
    base = PolishOptions(substeps=12, integrator="radau", cone_margins=(0.98,))
    levels = [ResolveLevel("coarse", reduced, base),
              ResolveLevel("refined", reduced, refine_by_defects(base, 12))]
    result = resolve_chain(levels, (Phase(STICK, 0, 1),), None, verbose=False)
    seen = [options for _, options in calls]
    assert result.status == "converged" and len(seen) == 2
    expected = [12] * 10
    expected[3] = expected[7] = 24
    assert seen[1].substeps == tuple(expected)
    assert seen[1].integrator == "radau" and seen[1].cone_margins == (0.98,)
    with pytest.raises(InvalidInput, match="needs a level before it"):
        refine_by_defects(base, 12)(None, reduced)


def test_a_level_that_would_solve_the_last_plans_nlp_again_is_skipped(reduced, stand_ins):
    """The first level's plan converged with every local defect within its share: the
    refined mesh is the same mesh, so its NLP is not solved again (it took 24 iterations
    and 32 s on the monoped to return the same plan); a level after a failed one is."""
    def fake(options, passed=True):
        plan = stand_in_plan("Solve_Succeeded", 1.0, verification=types.SimpleNamespace(
            passed=passed, summary=str, local_defects=(1e-4,) * 10))
        return dataclasses.replace(plan, integrator=options.integrator,
                                   substeps=options.substeps_per_interval(10))

    calls = stand_ins(fake)
    base = PolishOptions(substeps=12, integrator="radau")
    levels = [ResolveLevel("coarse", reduced, base),
              ResolveLevel("refined", reduced, refine_by_defects(base, 12))]
    result = resolve_chain(levels, (Phase(STICK, 0, 1),), None, verbose=False)
    assert len(calls) == 1 and [s.name for s in result.steps] == ["coarse"]
    assert result.status == "converged" and result.plan.substeps == (12,) * 10
    calls = stand_ins(lambda options: fake(options, passed=False))
    result = resolve_chain(levels, (Phase(STICK, 0, 1),), None, verbose=False)
    assert len(calls) == 1 + 2 and result.status == "verification_failed"  # one list


def test_a_chain_and_its_levels_are_checked(reduced):
    with pytest.raises(InvalidInput, match="at least one level"):
        resolve_chain([], (Phase(STICK, 0, 1),), None, verbose=False)
    with pytest.raises(InvalidInput, match="needs a ContactProblem"):
        ResolveLevel("bad", "monoped", PolishOptions())
    with pytest.raises(InvalidInput, match="needs PolishOptions"):
        ResolveLevel("bad", reduced, {"substeps": 8})


def test_the_path_constraints_are_measured_at_the_nodes():
    """The saved TF-9 plan keeps its path constraints (TF-9's ellipses among them) at its
    nodes; its foot moved 1 cm down into the first hole violates the hole's row by what
    the ellipse formula gives."""
    plan = saved_plan(types.SimpleNamespace(passed=True))
    mp = monoped_problem(EXACT_TASK)
    assert path_violation(mp.problem, plan) <= PATH_TOLERANCE
    foot = np.asarray(mp.foot(plan.x[:, :4].T)).T
    over_hole = np.flatnonzero(np.abs(foot[:, 0] - 0.5) < 0.05)[0]
    x = plan.x.copy()
    x[over_hole, 1] -= foot[over_hole, 1] + 0.05  # the foot 5 cm deep in the first hole
    inside = dataclasses.replace(plan, x=x)
    expected = -float(np.min(mp.hole_values(x[over_hole:over_hole + 1, :4])))
    assert expected > 0.1
    assert path_violation(mp.problem, inside) >= expected - 1e-12
    chain = ResolveChain(dataclasses.replace(inside, verification=types.SimpleNamespace(
        passed=True, summary=str)), mp.problem, (), path_violation(mp.problem, inside), 1.0)
    assert chain.status == "verification_failed" and not chain.success
    assert ResolveChain(None, mp.problem, (), float("nan"), 1.0).status == "chain_failed"
