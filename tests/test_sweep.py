"""Stability sweeps (`tfcontact.sweep`): the spec and its errors, the perturbed starts and,
on a `distributed.LocalCluster`, a small sweep of the TF-3 particle (N = 6, about 1-4 s a
case): its case files, resume, interrupt, a case that raises, the table and the chart."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re

import casadi as ca
import numpy as np
import pytest

from tfcontact.errors import InvalidInput
from tfcontact.fesd import Fesd, Standard
from tfcontact.mpcc import L1Penalty
from tfcontact.sweep import (
    GRID_PARAMETERS,
    HOPPER_PERTURBATION,
    SWEEP_TARGETS,
    CaseResult,
    CoordinateRange,
    InfeasibleStart,
    ParticleTarget,
    Perturbation,
    Progress,
    Silent,
    SweepCase,
    SweepSpec,
    add_sweep_parser,
    run_sweep,
    sweep_target,
)

# ---------------------------------------------------------------- the spec, fast


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"plan": "hopper", "starts": 0}, r"`starts` must be a positive integer, got 0"),
    ({"plan": "hopper", "starts": 2.5}, r"`starts` must be a positive integer, got 2.5"),
    ({"plan": "walker"}, r"unknown plan `walker`; sweepable plans: hopper, hopper-exact, particle"),
    ({"plan": "monoped"}, r"plan `monoped` has stages that solve problems of their own "
                          r"\(exact re-solve of TF-9's task, exact re-solve of TF-9's task, "
                          r"holes as terrain\), not the perturbed start's"),
    ({"plan": "hopper", "task": "sprint"},
     r"plan `hopper` has no task `sprint`; tasks: short, long, bench"),
    ({"plan": "hopper", "seed": -1}, r"`seed` must be a non-negative integer, got -1"),
    ({"plan": "hopper", "grid": {"gravity": [9.8]}},
     r"unknown grid key `gravity`; grid keys: friction, a_n, relaxation, scheme, n_fe, "
     r"ordering"),
    ({"plan": "hopper", "grid": {"n_fe": [0]}},
     r"`n_fe` values must be whole numbers >= 1, got 0"),
    ({"plan": "hopper", "grid": {"n_fe": ["2.5"]}},
     r"`n_fe` values must be whole numbers >= 1, got '2.5'"),
    ({"plan": "hopper", "grid": {"friction": []}}, r"grid key `friction` has no values"),
    ({"plan": "hopper", "grid": {"friction": [-0.1]}},
     r"`friction` values must be finite and >= 0 .*, got -0.1"),
    ({"plan": "hopper", "grid": {"a_n": ["0"]}},
     r"`a_n` values must be finite and > 0 .*, got 0.0"),
    ({"plan": "hopper", "grid": {"friction": ["soft"]}},
     r"`friction` values must be numbers, got 'soft'"),
    ({"plan": "hopper", "grid": {"relaxation": ["l2"]}},
     r"`relaxation` must be one of scholtes, l1, linf, got 'l2'"),
    ({"plan": "hopper", "grid": {"scheme": ["euler"]}},
     r"`scheme` must be one of fesd, standard, got 'euler'"),
    ({"plan": "hopper", "grid": {"friction": [0.5, "0.5"]}},
     r"grid key `friction` repeats a value: \[0.5, 0.5\]"),
])
def test_spec_rejects_bad_input(kwargs, message):
    with pytest.raises(InvalidInput, match=message):
        SweepSpec(**kwargs)


def test_a_plan_without_a_discovery_is_not_sweepable(monkeypatch):
    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import ExactResolve, Plan

    monkeypatch.setitem(plans.PLANS, "resolve", Plan("resolve", "re-solve only", ("only",),
                                                     (ExactResolve(),)))
    with pytest.raises(InvalidInput, match="plan `resolve` does not start with a discovery"):
        SweepSpec("resolve")


def test_spec_expands_the_grid_times_the_starts():
    spec = SweepSpec("hopper", starts=3, seed=7,
                     grid={"relaxation": ["scholtes", "l1"], "friction": ["0.5", 1]})
    assert spec.task == "short"  # the plan's first task
    # keys in GRID_PARAMETERS order whatever order they came in, numbers as floats
    assert spec.grid == (("friction", (0.5, 1.0)), ("relaxation", ("scholtes", "l1")))
    cases = spec.cases()
    assert len(cases) == 12 and len({c.case_id for c in cases}) == 12
    assert cases[0] == SweepCase((("friction", 0.5), ("relaxation", "scholtes")), 0, 7)
    assert cases[0].case_id == "friction=0.5_relaxation=scholtes_start=000"
    assert cases[-1].group == "friction=1, relaxation=l1"
    assert SweepSpec("particle", starts=2).cases()[1].case_id == "start=001"


def test_options_parameters_set_relaxation_and_discretisation():
    from tfcontact.mpcc import RELAXATIONS
    from tfcontact.scenes.hopper import hopper_options
    from tfcontact.sweep.spec import RELAXATION_NAMES

    assert RELAXATION_NAMES == tuple(RELAXATIONS)  # the parser's help names them all

    options = hopper_options("short")
    relaxed = GRID_PARAMETERS["relaxation"].apply(options, "l1")
    assert isinstance(relaxed.relaxation, L1Penalty)
    assert isinstance(GRID_PARAMETERS["scheme"].apply(options, "standard").method, Standard)
    # FESD keeps the plan's own settings (the hopper's gamma_h = 0.9)
    assert GRID_PARAMETERS["scheme"].apply(options, "fesd").method == Fesd(gamma_h=0.9)
    # the step size: finite elements per control interval, "2" from the command line
    n_fe = GRID_PARAMETERS["n_fe"]
    assert n_fe.check("2") == n_fe.check(2) == "2" and n_fe.label("2") == "n_fe=2"
    assert options.n_finite_elements == 3
    assert n_fe.apply(options, "2").n_finite_elements == 2
    # MUMPS's order in IPOPT's options, the plan's other IPOPT options kept
    ordered = GRID_PARAMETERS["ordering"].apply(options, "metis")
    assert ordered.nlp.options == {**options.nlp.options, "mumps_pivot_order": 5}
    assert "mumps_pivot_order" not in options.nlp.options
    with pytest.raises(InvalidInput, match="`ordering` must be one of auto, amd, pord, metis"):
        GRID_PARAMETERS["ordering"].check("colamd")


def test_a_case_runs_ipopts_blas_on_no_more_threads_than_its_task_states():
    """A case's NLPs run on the sweep's threads per case, but a task's stated
    `blas_threads` (the count its discovery was measured on) is not raised by it: the
    lower of the two. The shipped 3-D jump states 1; its homotopy stopped at IPOPT's cap
    on 2."""
    from tfcontact.mpcc import Ipopt
    from tfcontact.sweep.run import with_case_threads
    from tfcontact.task import load_task, shipped_tasks

    stated = load_task(shipped_tasks()["quadruped-jump"]).blas_threads
    assert stated == 1
    nlp = with_case_threads(Ipopt(blas_threads=stated), 2)
    assert (nlp.threads, nlp.blas_threads) == (2, 1)
    nlp = with_case_threads(Ipopt(), 1)  # the library's 2 lowered to the case's 1
    assert (nlp.threads, nlp.blas_threads) == (1, 1)
    nlp = with_case_threads(Ipopt(blas_threads=None), 3)  # none stated: the case's count
    assert (nlp.threads, nlp.blas_threads) == (3, 3)


def test_hopper_target_plans_from_the_start_it_is_given():
    """A perturbed start's reference spline begins at that start (the task's later way
    points unchanged); `reference_from_start=False` keeps the task's first way point."""
    from tfcontact.scenes.hopper import hopper_task
    from tfcontact.sweep.perturbation import PerturbedStart
    from tfcontact.sweep.targets import HopperTarget

    task = hopper_task("short")
    state = task.x0 + np.array([0.04, 0.02, 0.03, 0, 0, 0, 0, 0])
    moved = task.starting_at(state)
    assert moved.reference(np.array([0.0]))[0] == pytest.approx(state)
    assert moved.waypoints[1:] == task.waypoints[1:]
    end = np.array([task.horizon])
    assert moved.reference(end) == pytest.approx(task.reference(end))
    with pytest.raises(InvalidInput, match="8 finite numbers"):
        task.starting_at(state[:4])

    start = PerturbedStart(state[:4], state[4:], {"x": 0.04}, 1)
    for target, first in ((HopperTarget(), state), (HopperTarget(reference_from_start=False),
                                                    task.x0)):
        setup = target.setup("short", {})
        problem = target.from_start(setup, "short", {}, start)
        assert problem.q0 == pytest.approx(state[:4])
        # the running cost at the clock's start is the tracking error to `first`
        tf = problem.system
        cost = ca.Function("cost", [tf.y, tf.u], [problem.running_cost])
        y0 = np.asarray(tf.initial_state(state[:4], state[4:])).ravel()
        weights = np.asarray(task.state_weights)
        expected = float(np.sum(weights * (state - first) ** 2))
        assert float(cost(y0, np.zeros(2))) == pytest.approx(expected, abs=1e-9)
    assert HopperTarget().description() != HopperTarget(reference_from_start=False) \
        .description()


def test_hopper_target_sets_friction_and_a_n_in_its_task():
    target = SWEEP_TARGETS["hopper"]
    setup = target.setup("short", {"friction": 0.8, "a_n": 25.0})
    contact = setup.problem.system.cls.contacts[0]
    assert (contact.mu, contact.a_n) == (0.8, 25.0)
    assert setup.options.attempts == 3 and setup.problem.n_intervals == 20
    plain = target.setup("short", {}).problem.system.cls.contacts[0]
    assert (plain.mu, plain.a_n) == (0.45, 100.0)  # TF-8's short task


def test_particle_target_sets_friction_and_a_n_in_its_problem():
    target = SWEEP_TARGETS["particle"]
    contact = target.setup("reduced", {"friction": 0.3, "a_n": 50.0}).problem.system.cls \
        .contacts[0]
    assert (contact.mu, contact.a_n) == (0.3, 50.0)
    plain = target.setup("reduced", {}).problem.system.cls.contacts[0]
    assert plain.mu == 0.6 and plain.a_n == pytest.approx(9.81)  # TF-3: a_n = g


def test_failure_reasons_name_what_failed():
    """The solver's last IPOPT status, the verification check outside its tolerance, or
    the goal missed (a stand-in for `ContactResult`: only the fields read)."""
    from types import SimpleNamespace as NS

    from tfcontact.ocp.goals import GoalCheck, TaskReport
    from tfcontact.sweep.results import failure_reason

    tolerances = {"end_state": 5e-2, "gap": 1e-3, "cone": 1e-2, "clock": 1e-6}
    passed = NS(passed=True, tolerances=tolerances)
    ocp = NS(success=False, ipopt_status="Infeasible_Problem_Detected", residual=3e-3, n_nlps=10)
    done = TaskReport(())
    assert failure_reason(NS(ocp=ocp, status="nlp_failed", verification=passed, task=done)) \
        == ("nlp_failed: last IPOPT status Infeasible_Problem_Detected, complementarity "
            "residual 3.00e-03 after 10 NLPs", "nlp_failed")
    replay = NS(passed=False, tolerances=tolerances, end_state_deviation=2.9, min_gap=0.0,
                open_loop_unstable=False, clock_monotone=True, clock_end_error=0.0)
    assert failure_reason(NS(ocp=NS(success=True), verification=replay, task=done)) == (
        "end-state deviation 2.90e+00 > 5e-02", "verification: end state")
    missed = GoalCheck("end x", "end position x", 0.62, 0.7, False, "goal_missed")
    reason, kind = failure_reason(NS(ocp=NS(success=True), verification=passed,
                                     task=TaskReport((missed,))))
    assert kind == "task: goal_missed" and reason == missed.line().strip()


def test_a_case_after_later_stages_names_the_stage_that_failed():
    """A discovery that converged and a stance re-solve that did not: the case fails with
    the re-solve's status and line; a plan through the terrain fails at the collision
    check (stand-ins for `PlanOutcome`: only the fields read)."""
    from pathlib import Path
    from types import SimpleNamespace as NS

    from tfcontact.sweep.results import SweepResult

    found = CaseResult.from_error(SweepCase((), 0, 0), "walk", "task", RuntimeError("x"))
    found = dataclasses.replace(found, status="verification_failed", success=False,
                                first_attempt_success=False, attempts_used=1, iterations=800,
                                attempt_statuses=("verification_failed",), failure=None,
                                failure_kind=None)
    stages = [{"stage": "discover", "status": "converged", "seconds": 1.0},
              {"stage": "stance re-solve", "status": "nlp_failed", "iterations": 3000,
               "seconds": 2.0},
              {"stage": "collision check", "status": "clear", "seconds": 0.1}]
    trajectory = NS(solver={"objective": 3.2}, verification={"end_state_deviation": 0.7})
    outcome = NS(trajectory=trajectory, status="nlp_failed", success=False, task={},
                 summary="discovery: converged\nstances: nlp_failed, Maximum_Iterations\n"
                         "stances: verification PASSED (multi-contact): ...\n"
                         "task: all goals met")
    failed = found.after_stages(outcome, stages)
    assert (failed.status, failed.success, failed.first_attempt_success) == (
        "nlp_failed", False, False)
    assert failed.failure_kind == "stance re-solve: nlp_failed"
    # no line says FAILED: the line that states the status, not a passed check after it
    assert failed.failure == "stances: nlp_failed, Maximum_Iterations"
    # the plan's goals replace the discovery's, which stay on record beside them
    discovery_task = {"status": "goal_missed", "passed": False, "checks": []}
    planned = dataclasses.replace(found, extra={**found.extra, "task": discovery_task})
    recorded = planned.after_stages(outcome, stages).extra
    assert (recorded["task"], recorded["discovery_task"]) == ({}, discovery_task)
    assert "discovery_task" not in failed.extra  # a record without a discovery's goals
    assert (failed.iterations, failed.objective, failed.end_state_deviation) == (3800, 3.2, 0.7)
    # the re-solve's verdict, as `StancePlan.summary` words it
    assert failed.verification == "stances: verification PASSED (multi-contact): ..."
    # a replay that stopped before T: its deviation (inf) is written as null in the
    # trajectory; the case keeps its record (before: float(None) raised, and the sweep
    # saved a 40-minute solo12 trot case as an error with none of its figures)
    stopped = NS(trajectory=NS(solver={"objective": None},
                               verification={"end_state_deviation": None}),
                 status="verification_failed", success=False, task={}, summary="")
    kept = found.after_stages(stopped, stages)
    assert kept.status == "verification_failed" and kept.iterations == 3800
    assert math.isnan(kept.objective) and math.isnan(kept.end_state_deviation)
    stages[1]["status"], stages[2]["status"] = "converged", "penetration"
    through = NS(trajectory=trajectory, status="collision", success=False, task={},
                 summary="stances: converged\ncollisions FAILED: FL_LOWER_LEG 3 mm in the "
                         "terrain at 0.4 s\ntask: all goals met")
    failed = found.after_stages(through, stages)
    assert failed.failure_kind == "collision check: collision"
    assert failed.failure.startswith("collisions FAILED: FL_LOWER_LEG")
    passed = found.after_stages(NS(trajectory=trajectory, status="converged", success=True,
                                   task={}, summary="task: all goals met"),
                                [{**s, "status": "converged"} for s in stages[:2]])
    assert (passed.success, passed.first_attempt_success, passed.failure,
            passed.failure_kind) == (True, True, None, None)
    # a discovery whose relaxed plan failed its replay (as biped-walk's does) is not the
    # stage to blame when the re-solve after it fails
    stages = [{"stage": "discover", "status": "verification_failed", "seconds": 1.0},
              {"stage": "stance re-solve", "status": "nlp_failed", "iterations": 5,
               "seconds": 2.0},
              {"stage": "collision check", "status": "clear", "seconds": 0.1}]
    assert found.after_stages(outcome, stages).failure_kind == "stance re-solve: nlp_failed"
    # ... nor when the re-solve's plan fails its checks too (biped-walk's start 008: one
    # lift-off of a foot where two are asked); a re-solve that did not start hands on the
    # discovery's status, and the discovery is blamed
    missed = NS(trajectory=trajectory, status="verification_failed", success=False, task={},
                summary="task: goal missed")
    stages = [{"stage": "discover", "status": "verification_failed", "ran": True},
              {"stage": "stance re-solve", "status": "verification_failed", "ran": True,
               "iterations": 535},
              {"stage": "collision check", "status": "clear", "ran": True}]
    assert (found.after_stages(missed, stages).failure_kind
            == "stance re-solve: verification_failed")
    stages = [{"stage": "discover", "status": "nlp_failed", "ran": True},
              {"stage": "stance re-solve", "status": "nlp_failed", "ran": False,
               "iterations": 0},
              {"stage": "collision check", "status": "clear", "ran": True}]
    assert found.after_stages(outcome, stages).failure_kind == "discover: nlp_failed"
    table = SweepResult(SweepSpec("hopper", starts=1), Path("."),
                        (found.after_stages(outcome, stages),), 1, 0, 1.0, "here").table()
    assert "| verification_failed; then stance re-solve not started, collision check clear |" \
        in table
    # the table says what a case ran and names the failed stage
    table = SweepResult(SweepSpec("hopper", starts=2), Path("."), (failed, passed), 2, 0,
                        1.0, "here").table()
    assert ("Each case also ran the plan's later stages (stance re-solve, collision check)"
            in table)
    assert "| collision check: collision | 1 |" in table
    assert "| status | attempts, later stages |" in table
    assert ("| collision | verification_failed; then stance re-solve converged, collision "
            "check penetration |") in table
    assert "| converged | verification_failed; then stance re-solve converged |" in table


def test_later_stages_count_only_the_iterations_of_stages_that_ran(monkeypatch, tmp_path):
    """A stage that did not start hands on the discovery's trajectory: its iterations are
    not counted again; a stage that solved reports its own; the collision check runs on
    the last outcome (stand-ins for the stages, trajectories and the check)."""
    from types import SimpleNamespace as NS

    import tfcontact.scenes.plans
    from tfcontact.scenes.pipeline import PlanOutcome, Stage
    from tfcontact.sweep.run import run_later_stages

    class NotStarted(Stage):
        name = "not started"

        def run(self, given):
            return dataclasses.replace(given.previous, success=False)

    class Solves(Stage):
        name = "solves"

        def run(self, given):
            return PlanOutcome(NS(solver={"iterations": 42}), None, "converged", True, "ok")

    checked = []
    monkeypatch.setattr(tfcontact.scenes.plans, "check_collisions", lambda outcome: (
        checked.append(outcome) or outcome, {"status": "clear"}, None))
    found = PlanOutcome(NS(solver={"iterations": 3000}), None, "converged", True, "found")
    outcome, times = run_later_stages("p", "t", (NotStarted(), Solves()), found)
    assert [(t["stage"], t["status"]) for t in times] == [
        ("not started", "converged"), ("solves", "converged"), ("collision check", "clear")]
    assert [t.get("iterations") for t in times] == [0, 42, None]
    assert [t["ran"] for t in times] == [False, True, True]
    assert checked == [outcome] and outcome.summary == "ok"


def test_a_task_file_states_the_start_ranges_of_its_sweep(tmp_path):
    """`start_ranges` in a task file: a sweep perturbs those coordinates only, within their
    ranges (here the body along x and the front leg shortened: no height offset, so the
    other foot stays on the ground); a name the robot has not, or a range without
    low < high, is refused with the field named."""
    from strider import write_strider

    path = write_strider(tmp_path)
    text = path.read_text()
    path.write_text(text + "[start_ranges]\nx = [-0.02, 0.02]\nleg0 = [-0.02, -0.001]\n")
    target = sweep_target(str(path))
    setup = target.setup("task", {})
    perturbation = target.perturbation(setup)
    assert perturbation.to_dict() == {"x": [-0.02, 0.02], "leg0": [-0.02, -0.001]}
    names = list(setup.problem.system.cls.q_names)
    gaps = setup.problem.system.cls.function("gaps")
    for k in range(5):
        start = perturbation.sample(setup.problem, np.random.default_rng([0, k]))
        assert set(start.offsets) == {"x", "leg0"}
        assert abs(start.offsets["x"]) <= 0.02 and -0.02 <= start.offsets["leg0"] <= -0.001
        moved = np.flatnonzero(start.q0 != setup.problem.q0)
        assert [names[i] for i in moved] == ["x", "leg0"]
        gap = np.asarray(gaps(start.q0)).ravel()
        assert gap[0] > 0 and gap[1] == pytest.approx(0.0, abs=1e-9)  # toe0 up, toe1 down
    # without the table: the base's default ranges (the height only upwards)
    path.write_text(text)
    plain = sweep_target(str(path))
    assert "z" in plain.perturbation(plain.setup("task", {})).to_dict()
    for table, message in (("[start_ranges]\nheight = [0.0, 0.1]\n",
                            "`start_ranges` names ['height'], which the robot has not"),
                           ("[start_ranges]\nx = [0.1, -0.1]\n",
                            "`start_ranges.x` must have low < high, got [0.1, -0.1]")):
        path.write_text(text + table)
        with pytest.raises(InvalidInput, match=re.escape(message)):  # not "unknown plan"
            sweep_target(str(path)).setup("task", {})


# ---------------------------------------------------------------- perturbed starts


def test_hopper_starts_are_seeded_within_their_ranges_and_feasible():
    """x +-5 cm, base height up to 5 cm higher, pitch +-0.05 rad; the point foot's gap
    z - l cos(pitch) (ground lowered by the foot radius) is never negative."""
    problem = SWEEP_TARGETS["hopper"].setup("short", {}).problem
    starts = [HOPPER_PERTURBATION.sample(problem, np.random.default_rng([0, k]))
              for k in range(50)]
    again = HOPPER_PERTURBATION.sample(problem, np.random.default_rng([0, 3]))
    np.testing.assert_array_equal(again.q0, starts[3].q0)
    q0 = np.array([s.q0 for s in starts])
    delta = q0 - problem.q0
    assert np.all(np.abs(delta[:, 0]) <= 0.05)
    assert np.all((0 <= delta[:, 1]) & (delta[:, 1] <= 0.05))
    assert np.all(np.abs(delta[:, 2]) <= 0.05) and np.all(delta[:, 3] == 0)  # leg length
    assert np.all(np.array([s.v0 for s in starts]) == 0)
    gaps = q0[:, 1] - q0[:, 3] * np.cos(q0[:, 2])
    assert gaps.min() >= 0
    assert starts[0].offsets == pytest.approx(dict(zip(("x", "z", "pitch"), delta[0, :3],
                                                       strict=True)))


def test_a_start_below_the_ground_is_redrawn_then_refused():
    problem = SWEEP_TARGETS["hopper"].setup("short", {}).problem
    sinking = Perturbation((CoordinateRange("z", -0.05, -0.01),), max_tries=5)
    with pytest.raises(InfeasibleStart, match=r"no feasible start in 5 draws of "
                                              r"\{'z': \[-0.05, -0.01\]\}"):
        sinking.sample(problem, np.random.default_rng(0))
    # half the draws of [-0.02, +0.02] sink the foot: those are drawn again
    start = Perturbation((CoordinateRange("z", -0.02, 0.02),)).sample(
        problem, np.random.default_rng(1))
    assert start.offsets["z"] >= 0


def test_perturbation_errors_name_the_fix():
    problem = SWEEP_TARGETS["hopper"].setup("short", {}).problem
    with pytest.raises(InvalidInput, match=r"coordinates \['q_x'\] that the plan does not have"):
        Perturbation((CoordinateRange("q_x", 0, 1),)).sample(problem, np.random.default_rng())
    with pytest.raises(InvalidInput, match=r"`z` range must be finite with low <= high"):
        CoordinateRange("z", 0.1, 0.0)
    with pytest.raises(InvalidInput, match=r"no default perturbation for the coordinates"):
        Perturbation.from_names(("q_x", "q_z"))
    # the defaults by name are the hopper's ranges
    assert Perturbation.from_names(("x", "z", "pitch", "l")) == HOPPER_PERTURBATION


# ---------------------------------------------------------------- sweeps on a LocalCluster


def _table_counts(table: str) -> tuple[int, int, int]:
    """(cases, verified, verified at the first attempt) from the table's row `all`."""
    row = re.search(r"^\| all \| (\d+) \| (\d+)/\d+ .*? \| (\d+)/\d+ ", table, re.MULTILINE)
    assert row, table
    return int(row[1]), int(row[2]), int(row[3])


def _as_json(record: CaseResult) -> str:
    """The record as its case file holds it (nan compares equal as text)."""
    return json.dumps(record.to_dict(), indent=1) + "\n"


def _case_files(folder):
    return sorted((folder / "cases").glob("*.json"))


def test_sweep_runs_on_a_local_cluster_and_resumes(tmp_path, capsys):
    """The command's sweep of 2 starts x 2 relaxations: one case file each, the table's
    counts equal the files', a PNG chart, the workers' thread settings; a rerun solves
    nothing new; the caller's environment is as before (Dask's OMP_NUM_THREADS=1 for its
    workers does not stay behind)."""
    import os

    environment = dict(os.environ)
    parser = argparse.ArgumentParser()
    add_sweep_parser(parser.add_subparsers())
    out = tmp_path / "sweep"
    args = parser.parse_args(["sweep", "particle", "--task", "reduced", "--starts", "2",
                              "--relaxation", "scholtes", "linf", "--out", str(out)])
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert "4 to solve on a LocalCluster of 2 worker processes" in printed
    assert dict(os.environ) == environment
    assert "[4/4]" in printed and "particle (reduced): 4 cases" in printed

    files = _case_files(out)
    assert [f.stem for f in files] == sorted(c.case_id for c in SweepSpec(
        "particle", 2, "reduced", grid={"relaxation": ["scholtes", "linf"]}).cases())
    records = [json.loads(f.read_text()) for f in files]
    for record in records:
        assert {"params", "seed", "q0", "status", "success", "first_attempt_success",
                "attempts_used", "iterations", "objective", "times", "failure"} <= set(record)
        assert record["times"]["wall"] > 0 and record["extra"]["options"]["ipopt_threads"] == 1
    linf = [r for r in records if r["params"] == {"relaxation": "linf"}]
    assert all(r["extra"]["options"]["relaxation"] == "linf_penalty" for r in linf)
    table = (out / "table.md").read_text()
    assert _table_counts(table) == (4, sum(r["success"] for r in records),
                                    sum(r["first_attempt_success"] for r in records))
    assert "## By grid value" in table and "| relaxation=linf | 2 |" in table
    assert (out / "chart.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert ("the workers' OMP_NUM_THREADS=1, OPENBLAS_NUM_THREADS=1, MKL_NUM_THREADS=1"
            in table)

    spec = SweepSpec("particle", starts=2, task="reduced",
                     grid={"relaxation": ["scholtes", "linf"]})
    result = run_sweep(spec, out, progress=False)
    assert (result.solved, result.resumed) == (0, 4)
    assert [_as_json(c) for c in result.cases] == [
        (out / "cases" / f"{c.case_id}.json").read_text() for c in spec.cases()]
    assert result.n_success == sum(r["success"] for r in records)
    assert result.table() == (out / "table.md").read_text()
    assert len(json.loads((out / "sweep.json").read_text())["runs"]) == 1

    with pytest.raises(InvalidInput, match=r"holds another sweep \(seed: 0 there, 1 here\)"):
        run_sweep(SweepSpec("particle", starts=2, task="reduced", seed=1), out, progress=False)


class _StopAfterFirst(Progress):
    """Ctrl-C as the first case is reported."""

    def started(self, total, pending, cluster):
        pass

    def finished(self, record, done, pending, elapsed):
        raise KeyboardInterrupt

    def note(self, text):
        pass


def test_interrupted_sweep_keeps_its_finished_cases_and_resumes(tmp_path):
    spec = SweepSpec("particle", starts=2, task="reduced")
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, n_workers=1, progress=_StopAfterFirst())
    assert [f.stem for f in _case_files(tmp_path)] == ["start=000"]
    runs = json.loads((tmp_path / "sweep.json").read_text())["runs"]
    assert [(r["solved"], r["interrupted"]) for r in runs] == [(1, True)]
    result = run_sweep(spec, tmp_path, n_workers=1, progress=Silent())
    assert (result.solved, result.resumed) == (1, 1) and len(_case_files(tmp_path)) == 2


def test_a_sweep_says_it_is_running_while_no_case_finishes(tmp_path):
    """`Progress.heartbeat`: a line whenever no case finished for that long (here 10 ms:
    a case takes longer), before the case's own line."""
    import io

    from tfcontact.sweep.run import ProgressLines

    stream = io.StringIO()
    run_sweep(SweepSpec("particle", starts=1, task="reduced"), tmp_path, n_workers=1,
              progress=ProgressLines(stream, heartbeat=0.01))
    lines = stream.getvalue().splitlines()
    case = next(k for k, line in enumerate(lines) if line.startswith("[1/1]"))
    waiting = [line for line in lines[:case] if line.startswith("sweep: 0/1 solved, the "
                                                                 "others running or queued")]
    assert waiting and all(line.endswith(" s elapsed") for line in waiting)


def test_a_case_that_raises_is_recorded_and_solved_again(tmp_path, monkeypatch):
    """A start that cannot be drawn raises on the worker: the case is saved with status
    "error" and the exception, and a rerun tries it again."""
    below = ParticleTarget(name="particle-below", start_perturbation=Perturbation(
        (CoordinateRange("q_z", -2.0, -1.6),), max_tries=3))  # the particle starts at 1.5 m
    monkeypatch.setitem(SWEEP_TARGETS, "particle-below", below)
    spec = SweepSpec("particle-below", starts=1, task="reduced")
    result = run_sweep(spec, tmp_path, n_workers=1, progress=False)
    (case,) = result.cases
    assert (case.status, case.success, case.failure_kind) == ("error", False,
                                                              "error: InfeasibleStart")
    assert "no feasible start in 3 draws" in case.failure
    text = _case_files(tmp_path)[0].read_text()
    assert _as_json(CaseResult.from_dict(json.loads(text))) == text == _as_json(case)
    assert "| error: InfeasibleStart | 1 |" in (tmp_path / "table.md").read_text()
    assert run_sweep(spec, tmp_path, n_workers=1, progress=False).solved == 1


def test_a_case_past_its_time_limit_is_recorded_as_failed_and_solved_with_more_time(
        tmp_path):
    """Without a limit a case ran to its iteration caps (a planar solo12 gait's case past an
    hour, twice). With `case_time_limit` it stops at its first IPOPT iteration past the
    limit: failed, status time_limit, its start and times kept; a rerun with the same limit
    leaves it, one without a limit solves it."""
    spec = SweepSpec("particle", starts=1, task="reduced")
    result = run_sweep(spec, tmp_path, n_workers=1, progress=False, case_time_limit=1e-3)
    (case,) = result.cases
    assert (case.status, case.success, case.failure_kind) == ("time_limit", False,
                                                              "time limit")
    assert "stopped at the time limit of 0.001 s" in case.failure
    assert case.q0 and case.times["cpu"] > 0 and case.extra["time_limit"] == 1e-3
    text = _case_files(tmp_path)[0].read_text()
    assert _as_json(CaseResult.from_dict(json.loads(text))) == text == _as_json(case)
    assert "| time limit | 1 |" in (tmp_path / "table.md").read_text()
    runs = json.loads((tmp_path / "sweep.json").read_text())["runs"]
    assert runs[-1]["case_time_limit"] == 1e-3
    assert "at most 0.001 s each" in (tmp_path / "table.md").read_text()
    again = run_sweep(spec, tmp_path, n_workers=1, progress=False, case_time_limit=1e-3)
    assert again.solved == 0
    solved = run_sweep(spec, tmp_path, n_workers=1, progress=False)
    assert solved.solved == 1 and solved.cases[0].success


def test_a_case_along_a_given_sequence_stopped_at_its_limit_names_its_stage(tmp_path,
                                                                         monkeypatch):
    """A case with no discovery (a contact sequence given as data) stopped at its limit
    says it was in its stance solve, not in a discovery it does not have."""
    from strider import STRIDER_STEP, write_strider

    from tfcontact.errors import TimeLimitReached
    from tfcontact.sweep.run import solve_case

    def stopped(*args):
        raise TimeLimitReached(5.0, 5.1)

    monkeypatch.setattr("tfcontact.sweep.run.run_later_stages", stopped)
    write_strider(tmp_path)
    path = tmp_path / "step.toml"
    path.write_text(STRIDER_STEP + "\n[start_ranges]\nx = [-0.05, 0.05]\n")
    record = solve_case(sweep_target(str(path)), "task", SweepCase((), 0, 3), threads=1)
    assert (record.status, record.attempts_used, record.iterations) == ("time_limit", 0, 0)
    assert record.failure.endswith("(in its stance solve)"), record.failure
    assert record.offsets and record.times["wall"] > 0


def test_a_case_stopped_after_its_discovery_keeps_the_discovery_and_names_the_stage(
        monkeypatch):
    """A case whose limit passes in a stage after its discovery: the record keeps the
    discovery's solve (attempts, iterations) and says where it stopped."""
    from tfcontact.errors import TimeLimitReached
    from tfcontact.scenes.pipeline import Stage
    from tfcontact.sweep.run import solve_case

    class Slow(Stage):
        name = "stance re-solve"

        def run(self, given):
            raise TimeLimitReached(5.0, 5.2)

    target = sweep_target("particle")
    monkeypatch.setattr(type(target), "later_stages", lambda self, task: (Slow(),))
    # the particle has no robot to hand on: its discovery's result goes to the stage
    monkeypatch.setattr("tfcontact.scenes.pipeline.discovery_outcome",
                        lambda result, setup: result)
    monkeypatch.setattr("tfcontact.sweep.run.run_later_stages",
                        lambda plan, task, stages, found: stages[0].run(found))
    record = solve_case(target, "reduced", SweepCase((), 0, 0), threads=1, time_limit=60.0)
    assert (record.status, record.success, record.failure_kind) == ("time_limit", False,
                                                                    "time limit")
    assert record.failure.startswith("stopped at the time limit of 5 s")
    assert "in the stages after discovery 1 (converged): stance re-solve" in record.failure
    assert record.attempts_used == 1 and record.iterations > 0
    assert record.extra["attempts"][0]["status"] == "converged"
    assert record.extra["time_limit"] == 5.0 and record.times["cpu"] > 0
    assert CaseResult.from_dict(json.loads(json.dumps(record.to_dict()))) == record


def recorded_stance_solves(monkeypatch) -> list:
    """The (start q0, plan, IPOPT's threads) of every `resolve_stances` a stage makes, as
    it makes them."""
    from tfcontact.scenes import pipeline

    solved = []
    resolve = pipeline.resolve_stances

    def recording(problem, stances, options, *args, **kwargs):
        plan = resolve(problem, stances, options, *args, **kwargs)
        solved.append((problem.q0.copy(), plan, (options.threads, options.blas_threads)))
        return plan

    monkeypatch.setattr(pipeline, "resolve_stances", recording)
    return solved


@pytest.mark.slow
def test_a_case_runs_the_plans_later_stages_from_its_perturbed_start(tmp_path, monkeypatch):
    """A task file with `exact_resolve`: a case's discovery from its perturbed start,
    then the stance re-solve of that discovery's problem (the same start) and the
    collision check, as `tfcontact plan` runs them, the whole plan again while it fails
    (the default preset's 3 runs); the record is the whole plan's."""
    from strider import write_strider

    from tfcontact.sweep.run import solve_case
    from tfcontact.task.presets import default_preset

    solved = recorded_stance_solves(monkeypatch)
    target = sweep_target(str(write_strider(tmp_path)))
    record = solve_case(target, "task", SweepCase((), 0, 3), threads=1)
    stages = record.extra["stages"]
    runs = stages[-1]["run"]
    assert [(s["stage"], s["run"]) for s in stages] == [
        (stage, run) for run in range(1, runs + 1)
        for stage in ("discover", "stance re-solve", "collision check")]
    assert record.attempts_used == runs  # one discovery solve per run
    assert max(abs(v) for v in record.offsets.values()) > 1e-3  # the start moved
    for q0, _, threads in solved:
        np.testing.assert_array_equal(q0, record.q0)
        assert threads == (1, 1)  # the case's threads, not the plan's 2
    q0, plan, _ = solved[-1]  # the last run's re-solve is the plan
    assert record.objective == plan.cost
    assert stages[-2]["iterations"] == plan.iterations
    discovery = sum(a["iterations"] for a in record.extra["attempts"])  # every run's
    assert record.iterations == discovery + sum(p.iterations for _, p, _ in solved)
    assert len(record.extra["attempts"]) == runs
    for attempt in record.extra["attempts"]:  # each discovery's NLPs on record
        assert attempt["nlps"][0]["sigma"] == default_preset().homotopy.sigma_0
        assert sum(nlp["iterations"] for nlp in attempt["nlps"]) == attempt["iterations"]
    assert record.success == plan.success
    assert record.status == "converged", record.failure
    assert stages[-1]["status"] == "clear"
    assert CaseResult.from_dict(json.loads(json.dumps(record.to_dict()))) == record


def test_a_given_contact_sequence_is_swept_from_perturbed_starts(tmp_path, monkeypatch):
    """A task with `[[stances]]` (no discovery): a case solves along the given sequence
    from its perturbed start (the task stated from there), verified and collision checked
    as `tfcontact plan` runs it; its record is that stage's. Grid keys, which set a
    discovery, are refused; a start that lifts the first stance's contacts off the ground
    (the strider's default ranges raise its base) is a case that errs, naming why."""
    from pathlib import Path

    from strider import STRIDER_STEP, write_strider

    from tfcontact.sweep.results import SweepResult
    from tfcontact.sweep.run import solve_case

    solved = recorded_stance_solves(monkeypatch)
    write_strider(tmp_path)
    path = tmp_path / "step.toml"
    # its starts along x only: the first stance's toes stay on the ground
    path.write_text(STRIDER_STEP + "\n[start_ranges]\nx = [-0.05, 0.05]\n")
    target = sweep_target(str(path))
    record = solve_case(target, "task", SweepCase((), 0, 3), threads=1)
    assert [s["stage"] for s in record.extra["stages"]] == ["stance solve", "collision check"]
    assert max(abs(v) for v in record.offsets.values()) > 1e-3  # the start moved
    (q0, plan, threads), = solved
    np.testing.assert_array_equal(q0, record.q0)
    assert threads == (1, 1)  # the case's threads, not the plan's 2
    assert record.objective == plan.cost and record.iterations == plan.iterations
    assert record.status == "converged" and record.success, record.failure
    assert "verification PASSED" in record.verification
    assert CaseResult.from_dict(json.loads(json.dumps(record.to_dict()))) == record
    table = SweepResult(SweepSpec(str(path), starts=1), Path("."), (record,), 1, 0, 1.0,
                        "here").table()
    assert ("Each case ran the plan's stages (stance solve, collision check) as `tfcontact "
            "plan` does, with no discovery") in table
    with pytest.raises(InvalidInput, match="given as data: the grid keys"):
        SweepSpec(str(path), grid={"relaxation": ["scholtes"]})
    path.write_text(STRIDER_STEP)
    with pytest.raises(InvalidInput, match="the first stance closes contacts"):
        solve_case(sweep_target(str(path)), "task", SweepCase((), 0, 3), threads=1)


def test_a_sweep_keeps_each_cases_plan_as_a_trajectory_file(tmp_path):
    """A case with a robot to draw: its plan is written as plans/<case>.npz (+ sidecar),
    the trajectory of its perturbed start that `tfcontact replay` and `check` read, and
    the case record stays JSON without it; a target without a robot (the particle)
    writes no plan file."""
    from strider import STRIDER_STEP, write_strider

    from tfcontact.plan_format import check_plan, load_trajectory

    write_strider(tmp_path)
    path = tmp_path / "step.toml"
    path.write_text(STRIDER_STEP + "\n[start_ranges]\nx = [-0.05, 0.05]\n")
    out = tmp_path / "sweep"
    result = run_sweep(SweepSpec(str(path), starts=1), out, n_workers=1, progress=False)
    (case,) = result.cases
    assert case.success, case.failure
    assert case.trajectory is None  # written, not kept in memory
    record = json.loads((out / "cases" / "start=000.json").read_text())
    assert "trajectory" not in record
    plan = load_trajectory(out / "plans" / "start=000.npz")
    assert (out / "plans" / "start=000.json").exists()
    np.testing.assert_allclose(plan.q[0], record["q0"], atol=1e-12)  # the moved start
    assert max(abs(v) for v in record["offsets"].values()) > 1e-3
    assert plan.solver["objective"] == pytest.approx(record["objective"], rel=1e-12)
    assert check_plan(plan).passed
    particle = tmp_path / "particle"
    run_sweep(SweepSpec("particle", starts=1, task="reduced"), particle, n_workers=1,
              progress=False)
    assert (particle / "cases" / "start=000.json").exists()
    assert not (particle / "plans").exists()


def test_a_discovery_only_case_keeps_its_failed_plan():
    """A target whose plan is its discovery alone (the hopper's), cut to one NLP of 15
    IPOPT iterations so that it fails: the record carries the failed plan's trajectory,
    from the case's perturbed start, with the record's status."""
    from tfcontact.sweep.run import solve_case
    from tfcontact.sweep.targets import HopperTarget

    @dataclasses.dataclass(frozen=True)
    class CutHopper(HopperTarget):
        def setup(self, task, params):
            setup = super().setup(task, params)
            cut = dataclasses.replace(
                setup.options, attempts=1,
                homotopy=dataclasses.replace(setup.options.homotopy, max_nlps=1),
                nlp=dataclasses.replace(setup.options.nlp, max_iter=15))
            return dataclasses.replace(setup, options=cut)

    record = solve_case(CutHopper(), "short", SweepCase((), 0, 1), threads=1)
    assert not record.success
    plan = record.trajectory
    np.testing.assert_allclose(plan.q[0], record.q0, atol=1e-12)
    assert max(abs(v) for v in record.offsets.values()) > 1e-3
    assert plan.status == record.status


def test_a_task_files_case_is_the_task_stated_from_its_perturbed_start(tmp_path):
    """A task file's case plans from its start as a user standing there would state it:
    the tracked splines begin at the perturbed start (the tracking cost vanishes there at
    t = 0), not at the file's start; the goals and way points stay."""
    from types import SimpleNamespace as NS

    from strider import write_strider

    from tfcontact.sweep.perturbation import perturbed_problem

    target = sweep_target(str(write_strider(tmp_path)))
    setup = target.setup("task", {})
    names = setup.problem.system.cls.q_names
    q0 = setup.problem.q0.copy()
    q0[names.index("x")] += 0.03
    q0[names.index("z")] += 0.01
    start = NS(q0=q0, v0=setup.problem.v0)
    moved = target.from_start(setup, "task", {}, start)
    np.testing.assert_array_equal(moved.q0, q0)

    def tracking_at_start(problem):
        tf = problem.system
        y = np.zeros(tf.y.numel())
        y[tf.q_index], y[tf.v_index] = problem.q0, problem.v0  # clock 0
        cost = ca.Function("cost", [tf.y, tf.u], [problem.running_cost])
        return float(cost(y, np.zeros(tf.u.numel())))

    assert tracking_at_start(moved) == pytest.approx(0.0, abs=1e-12)
    # only the start replaced: x and z tracked from the file's start, 50 dx^2 + 500 dz^2
    assert tracking_at_start(perturbed_problem(setup.problem, start)) == pytest.approx(
        50 * 0.03 ** 2 + 500 * 0.01 ** 2)
    assert moved.goals == setup.problem.goals
    # the sweep file says so: a folder of cases that only replaced the start is not resumed
    assert target.description() == {"reference": "from the start"}
    assert sweep_target("hopper-exact").description() == {}


def test_a_case_runs_a_failed_plan_again_whole_from_its_next_seed(tmp_path, monkeypatch):
    """A plan with `whole_attempts` (a task file's `attempts` with `exact_resolve`): a case
    whose re-solved plan failed runs the discovery again from the next seed and the later
    stages on it, as `tfcontact plan` does; the record counts every run (stand-ins for the
    solver: only the fields read)."""
    from types import SimpleNamespace as NS

    from strider import write_strider

    from tfcontact.ocp import contact
    from tfcontact.ocp.contact import Attempt
    from tfcontact.scenes import pipeline
    from tfcontact.sweep import results, run
    from tfcontact.sweep.results import SweepResult
    from tfcontact.sweep.run import solve_case

    path = write_strider(tmp_path)
    path.write_text(path.read_text().replace("exact_resolve = true",
                                             "exact_resolve = true\nattempts = 3"))
    seeds = []

    def discovery(problem, options, *, first_seed, verbose):
        seeds.append((first_seed, options.attempts))
        return NS(attempts=(Attempt(first_seed or None, "verification_failed", 100 + first_seed,
                                    1.0, 0.1, 2.0),),
                  status="verification_failed", success=False, problem=problem,
                  ocp=NS(cost=1.0, residual=1e-3, success=True), options=options,
                  verification=NS(end_state_deviation=2.0, summary=lambda: "relaxed"),
                  timings={"build": 0.1, "solve": 1.0, "verify": 0.1},
                  task=NS(to_dict=dict))

    def later(plan, task, stages, found):
        good = found == 1  # the second run's discovery
        status = "converged" if good else "goal_missed"
        return (NS(trajectory=None, status=status, success=good, task={}, summary=status),
                [{"stage": "stance re-solve", "status": status, "iterations": 10,
                  "seconds": 1.0}])

    monkeypatch.setattr(contact, "solve_contact", discovery)
    monkeypatch.setattr(pipeline, "discovery_outcome",
                        lambda result, setup: result.attempts[0].iterations - 100)
    monkeypatch.setattr(run, "run_later_stages", later)
    monkeypatch.setattr(results, "failure_reason", lambda result: ("relaxed", "verification"))
    record = solve_case(sweep_target(str(path)), "task", SweepCase((), 0, 3), threads=1)
    assert seeds == [(0, 1), (1, 1)]
    assert (record.status, record.success, record.first_attempt_success) == (
        "converged", True, False)
    assert record.attempts_used == 2
    assert [(a["seed"], a["iterations"]) for a in record.extra["attempts"]] == [
        (None, 100), (1, 101)]
    assert record.iterations == 100 + 101 + 2 * 10
    assert [(s["stage"], s["run"]) for s in record.extra["stages"]] == [
        ("discover", 1), ("stance re-solve", 1), ("discover", 2), ("stance re-solve", 2)]
    table = SweepResult(SweepSpec("hopper", starts=1), tmp_path, (record,), 1, 0, 1.0,
                        "here").table()
    assert ("verification_failed > verification_failed; then stance re-solve goal_missed; "
            "run 2: discover verification_failed, stance re-solve converged") in table
    assert "ran the whole plan again" in table


def test_a_cases_discovery_drops_the_rows_only_the_stance_re_solve_keeps(tmp_path,
                                                                         monkeypatch):
    """A body kept by the stance re-solve only (`discovery = false`): the case's discovery
    solves without its row, as the plan's `Discover` stage does, and its later stages get
    the whole problem (before, the case's discovery kept the row: quadruped-gait's start
    at x + 0.014 then took 33 + 56 IPOPT iterations where `tfcontact plan` took 31 + 42)."""
    from types import SimpleNamespace as NS

    from strider import write_strider

    from tfcontact.ocp import contact
    from tfcontact.scenes import pipeline
    from tfcontact.sweep import results, run
    from tfcontact.sweep.run import solve_case

    path = write_strider(tmp_path)
    path.write_text(path.read_text() + '[[bodies]]\nframe = "body"\nradius = 0.05\n'
                    'discovery = false\n')
    solved, later_got = [], []

    def discovery(problem, options, *, first_seed, verbose):
        solved.append(problem)
        return NS(attempts=(), status="converged", success=True, problem=problem,
                  ocp=NS(cost=1.0, residual=1e-4, success=True), options=options,
                  verification=NS(end_state_deviation=0.0, summary=lambda: "ok"),
                  timings={"build": 0.1, "solve": 1.0, "verify": 0.1},
                  task=NS(to_dict=dict))

    def later(plan, task, stages, found):
        later_got.append(found)
        return (NS(trajectory=None, status="converged", success=True, task={},
                   summary="ok"), [])

    monkeypatch.setattr(contact, "solve_contact", discovery)
    monkeypatch.setattr(pipeline, "discovery_outcome", lambda result, setup: setup.problem)
    monkeypatch.setattr(run, "run_later_stages", later)
    monkeypatch.setattr(results, "failure_reason", lambda result: ("", ""))
    target = sweep_target(str(path))
    solve_case(target, "task", SweepCase((), 0, 3), threads=1)
    whole = target.setup("task", {}).problem.path.expression.numel()
    assert later_got[0].path.expression.numel() == whole
    assert solved[0].path.expression.numel() == whole - 1


@pytest.mark.parametrize(("argv", "message"), [
    (["hopper", "--starts", "0"], "`starts` must be a positive integer, got 0"),
    (["monoped"], "plan `monoped` has stages that solve problems of their own"),
    (["hopper", "--friction", "-1"], "`friction` values must be finite and >= 0"),
    (["hopper", "--workers", "0"], "`n_workers` must be a positive integer, got 0"),
    (["hopper", "--threads", "0"], "`threads_per_case` must be a positive integer, got 0"),
    (["hopper", "--time-limit", "0"], "`case_time_limit` must be None or a number > 0"),
])
def test_command_exits_2_on_bad_input(argv, message, capsys, tmp_path):
    parser = argparse.ArgumentParser()
    add_sweep_parser(parser.add_subparsers())
    args = parser.parse_args(["sweep", *argv, "--out", str(tmp_path / "never")])
    assert args.func(args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "never").exists()


def test_command_threads_reach_the_cases(monkeypatch, tmp_path):
    """`--threads 2` is each case's IPOPT threads (`SweepSpec.threads_per_case`, which
    `solve_case` receives); without it 1."""
    import tfcontact.sweep.run as run

    seen = []

    def stopped(spec, *args, **kwargs):  # the sweep as Ctrl-C leaves it: nothing solved
        seen.append(spec)
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "run_sweep", stopped)
    parser = argparse.ArgumentParser()
    add_sweep_parser(parser.add_subparsers())
    for extra, threads in ((["--threads", "2"], 2), ([], 1)):
        args = parser.parse_args(["sweep", "hopper", "--out", str(tmp_path), *extra])
        assert args.func(args) == 130
        assert seen[-1].threads_per_case == threads


def test_the_parser_does_not_load_the_solver():
    """`tfcontact --help` builds the sweep's parser: CasADi, Dask and the plans wait for a
    sweep to run."""
    import subprocess
    import sys

    code = ("import sys, argparse, tfcontact.sweep.cli as c; "
            "c.add_sweep_parser(argparse.ArgumentParser().add_subparsers()); "
            "print(sorted(m for m in ('casadi', 'distributed', 'tfcontact.scenes') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_a_continued_discovery_is_swept_with_its_task_stated_from_the_cases_start(
        tmp_path, monkeypatch):
    """A task with `[continuation]` (biped-step's route): a case perturbs the start of the
    discovery it continues, and the continuation's own task is stated from that start too
    (`Stage.at_start`: its reference splines begin there) instead of the sweep refusing
    the plan; outside a sweep the stage keeps its task's start (stand-ins for the
    solver's outcomes: only the fields read)."""
    from types import SimpleNamespace as NS

    from strider import STRIDER_TASK, write_strider

    from tfcontact.ocp import contact
    from tfcontact.scenes import pipeline
    from tfcontact.sweep import results, run
    from tfcontact.sweep.run import solve_case

    write_strider(tmp_path)
    path = tmp_path / "further.toml"
    path.write_text(STRIDER_TASK.replace('name = "strider-shift"', 'name = "strider-further"')
                    .replace("x = 0.02", "x = 0.03")
                    + '\n[continuation]\ntask = "strider.toml"\nsigma = 0.001\n')
    target = sweep_target(str(path))  # refused before: a stage with its own problem
    continued = target.later_stages("task")[0]
    assert continued.continue_sigma == 0.001
    task_start = continued.build("task").problem.q0
    moved = task_start + 0.01
    restated = continued.at_start(moved, np.zeros_like(moved)).build("task").problem
    np.testing.assert_array_equal(restated.q0, moved)
    assert restated.goals == continued.build("task").problem.goals  # the same task
    np.testing.assert_array_equal(continued.build("task").problem.q0, task_start)

    def discovery(problem, options, *, first_seed, verbose):
        return NS(attempts=(contact.Attempt(None, "converged", 10, 1.0, 0.1, 0.0),),
                  status="converged", success=True, problem=problem,
                  ocp=NS(cost=1.0, residual=1e-6, success=True), options=options,
                  verification=NS(end_state_deviation=0.0, summary=lambda: "relaxed"),
                  timings={"build": 0.1, "solve": 1.0, "verify": 0.1},
                  task=NS(to_dict=dict))

    handed = []

    def later(plan, task, stages, found):
        handed.append(stages)
        return (NS(trajectory=None, status="converged", success=True, task={},
                   summary="converged"), [])

    monkeypatch.setattr(contact, "solve_contact", discovery)
    monkeypatch.setattr(pipeline, "discovery_outcome", lambda result, setup: None)
    monkeypatch.setattr(run, "run_later_stages", later)
    monkeypatch.setattr(results, "failure_reason", lambda result: (None, None))
    record = solve_case(target, "task", SweepCase((), 0, 1), threads=1)
    (stages,) = handed
    assert [s.name for s in stages] == ["discover", "stance re-solve"]
    assert max(abs(v) for v in record.offsets.values()) > 1e-3  # the start moved
    np.testing.assert_array_equal(stages[0].build("task").problem.q0, record.q0)
