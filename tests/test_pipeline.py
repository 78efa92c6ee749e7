"""One pipeline for every plan: a named plan is data (tasks, stages) and `run_plan` runs
its stages in turn, each given the outcome of the one before."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import pytest

from tfcontact.errors import InvalidInput
from tfcontact.ocp.goals import EndPosition, LiftOffs
from tfcontact.scenes import plans
from tfcontact.scenes.pipeline import (
    LIFT_OFF_MARGIN,
    Discover,
    ExactResolve,
    Plan,
    PlanOutcome,
    Stage,
    StageInput,
    lift_off_heights,
)
from tfcontact.scenes.plans import PLANS
from tfcontact.sweep import SweepSpec, sweep_target


@dataclass(frozen=True)
class _Record(Stage):
    """A stage that notes what it was given and passes a new status on."""

    status: str
    seen: list
    name: str = "record"
    tasks: tuple[str, ...] | None = None
    pause: float = 0.0

    def run(self, given: StageInput) -> PlanOutcome:
        time.sleep(self.pause)
        self.seen.append((given.plan, given.task, None if given.previous is None
                          else given.previous.status))
        return PlanOutcome(None, None, self.status, self.status == "converged", self.status)


def test_stages_run_in_turn_and_the_last_outcome_is_written(tmp_path, monkeypatch):
    seen: list = []
    plan = Plan("two", "two stages", ("only",),
                (_Record("first", seen, pause=0.2), _Record("converged", seen)))
    monkeypatch.setitem(plans.PLANS, "two", plan)
    report = plans.run_plan("two", tmp_path / "out", verbose=False)
    assert seen == [("two", "only", None), ("two", "only", "first")]
    assert (report.success, report.status) == (True, "converged")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "converged"
    # where the time went: each stage, the collision check and the files
    stages = summary["stages"]
    assert [(s["stage"], s["status"]) for s in stages[:3]] == [
        ("record", "first"), ("record", "converged"), ("collision check", "not checked")]
    assert stages[3]["stage"].startswith("files")
    assert stages[0]["seconds"] >= 0.2 > stages[1]["seconds"]
    assert sum(s["seconds"] for s in stages) <= summary["wall_time"]


def test_plans_are_data():
    assert [s.name for s in PLANS["hopper"].stages] == ["discover"]
    assert [s.name for s in PLANS["hopper-exact"].stages] == ["discover", "exact re-solve"]
    assert [type(s) for s in PLANS["monoped"].stages] == [Discover, ExactResolve, ExactResolve,
                                                           ExactResolve]
    assert PLANS["hopper"].build is PLANS["hopper"].stages[0].build
    with pytest.raises(InvalidInput, match="needs stages"):
        Plan("none", "no stages", ("only",), ())
    with pytest.raises(InvalidInput, match=r"names tasks \['long'\] the plan does not have"):
        Plan("one", "one stage", ("short",), (ExactResolve(tasks=("long",)),))


def test_a_stage_runs_only_for_its_tasks(tmp_path, monkeypatch):
    seen: list = []
    plan = Plan("two", "two stages", ("short", "long"),
                (_Record("first", seen), _Record("converged", seen, tasks=("long",))))
    monkeypatch.setitem(plans.PLANS, "two", plan)
    report = plans.run_plan("two", tmp_path / "short", task="short", verbose=False)
    assert report.status == "first" and seen == [("two", "short", None)]
    report = plans.run_plan("two", tmp_path / "long", task="long", verbose=False)
    assert report.status == "converged" and seen[1:] == [("two", "long", None),
                                                          ("two", "long", "first")]


@dataclass(frozen=True)
class _SeededDiscovery(Discover):
    """A discovery without a solver: notes the seed and attempts it was given."""

    build: object = None
    seen: list = field(default_factory=list)

    def run(self, given: StageInput) -> PlanOutcome:
        self.seen.append((given.seed, given.attempts))
        return PlanOutcome(None, None, "verification_failed", False, "relaxed")


@dataclass(frozen=True)
class _ExactFrom(Stage):
    """A re-solve whose plan succeeds from the discovery of seed `first_good` on."""

    first_good: int
    name: str = "re-solve"
    tasks: tuple[str, ...] | None = None

    def run(self, given: StageInput) -> PlanOutcome:
        good = given.seed >= self.first_good
        status = "converged" if good else "goal_missed"
        return PlanOutcome(None, None, status, good, status)


def test_a_plan_with_whole_attempts_runs_again_from_its_discovery(tmp_path, monkeypatch):
    """`Plan.whole_attempts`: a re-solved plan that fails runs the whole pipeline again,
    its discovery one solve from the next seed, until it succeeds; `--attempts` sets the
    runs; each stage's entry names its run."""
    discovery = _SeededDiscovery()
    monkeypatch.setitem(plans.PLANS, "walk", Plan("walk", "walk", ("only",),
                                                  (discovery, _ExactFrom(2)),
                                                  whole_attempts=3))
    report = plans.run_plan("walk", tmp_path / "three", verbose=False)
    assert (report.success, report.status) == (True, "converged")
    assert discovery.seen == [(0, 1), (1, 1), (2, 1)]
    stages = json.loads((tmp_path / "three" / "summary.json").read_text())["stages"]
    assert [(s["stage"], s["status"], s.get("run")) for s in stages[:-1]] == [
        (stage, status, run) for run, status in ((1, "goal_missed"), (2, "goal_missed"),
                                                 (3, "converged"))
        for stage, status in (("discover", "verification_failed"), ("re-solve", status),
                              ("collision check", "not checked"))]
    discovery.seen.clear()
    report = plans.run_plan("walk", tmp_path / "two", attempts=2, verbose=False)
    assert (report.success, report.status) == (False, "goal_missed")
    assert discovery.seen == [(0, 1), (1, 1)]
    with pytest.raises(InvalidInput, match="`whole_attempts` needs a Discover first"):
        Plan("own", "own", ("only",), (_Record("converged", []),), whole_attempts=2)
    for runs in (0, 1.5, True):
        with pytest.raises(InvalidInput, match="`whole_attempts` must be a positive integer"):
            Plan("walk", "walk", ("only",), (discovery,), whole_attempts=runs)


def test_an_exact_resolve_needs_a_discovery_before_it(tmp_path):
    given = StageInput("p", "t", tmp_path, False, None, None)
    with pytest.raises(InvalidInput, match="needs a discovery stage before it"):
        ExactResolve().run(given)


def test_attempts_only_for_plans_with_a_discovery(tmp_path, monkeypatch):
    monkeypatch.setitem(plans.PLANS, "own", Plan("own", "own", ("only",),
                                                 (_Record("converged", []),)))
    with pytest.raises(InvalidInput, match="has no discovery whose attempts could be set"):
        plans.run_plan("own", tmp_path / "out", attempts=2, verbose=False)


def test_a_sweep_runs_later_stages_but_refuses_those_with_problems_of_their_own():
    """A case runs a plan's stages after its discovery on the perturbed start's outcome;
    a stage that builds its own problem would ignore that start."""
    assert [s.name for s in sweep_target("hopper-exact").later_stages("bench")] == [
        "exact re-solve"]
    assert sweep_target("hopper").later_stages("short") == ()
    with pytest.raises(InvalidInput, match="stages that solve problems of their own "
                                           "\\(exact re-solve of TF-9's task, exact "
                                           "re-solve of TF-9's task, holes as terrain\\)"):
        SweepSpec("monoped")


@pytest.mark.slow
def test_hopper_exact_is_discovered_then_resolved_exactly(tmp_path):
    """`tfcontact plan hopper-exact`: the bench hop found by the time-freezing homotopy,
    then re-solved along its contact sequence with the lift-off at a control jump; the
    exact plan agrees with the exact-impact replay far closer than the discovery."""
    from tfcontact.cli import main

    out = tmp_path / "exact"
    assert main(["plan", "hopper-exact", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "converged" and summary["success"]
    assert "discovery: converged" in summary["summary"]
    assert "polish: verification PASSED" in summary["summary"]
    sidecar = json.loads((out / "trajectory.json").read_text())
    phases = sidecar["solver"]["phases"]
    assert [p["mode"] for p in phases][:2] == ["stick", "flight"]
    # the lift-off moved to a control jump k T / N (T / N = 0.05 s)
    assert phases[1]["start"] / 0.05 == pytest.approx(round(phases[1]["start"] / 0.05))
    assert summary["task_checks"]["passed"]


def test_discover_is_the_build_path_of_task_files(tmp_path):
    from tfcontact.scenes.plans import task_plan
    from tfcontact.task import shipped_tasks

    plan = task_plan(str(shipped_tasks()["hopper-vertical"]))
    assert [type(s) for s in plan.stages] == [Discover]


def test_a_resolve_with_nothing_to_follow_keeps_the_outcome_before(tmp_path):
    """A start that finds nothing to follow: the stage before's outcome (its trajectory
    kept, never lost) with the reason, and a failed status: "chain_failed" where the stage
    before had succeeded, its own failure otherwise."""
    from tfcontact.scenes.pipeline import NoStart, PlanSetup, ResolveStart

    class Nothing(ResolveStart):
        def begin(self, given, levels):
            raise NoStart("the hop did not lift off")

    setup = PlanSetup(None, None, None, {})
    stage = ExactResolve(levels=lambda setup: (), start=Nothing())
    for status, success, expected in (("converged", True, "chain_failed"),
                                      ("nlp_failed", False, "nlp_failed")):
        before = PlanOutcome("trajectory", None, status, success, "discovered", setup=setup)
        outcome = stage.run(StageInput("p", "t", tmp_path, False, None, before))
        assert (outcome.status, outcome.success) == (expected, False)
        assert outcome.trajectory == "trajectory"
        assert outcome.summary == "discovered\nexact re-solve not started: the hop did not " \
                                  "lift off"


def test_a_re_solve_goes_on_from_the_verified_plan_before(tmp_path):
    """`PreviousPlan`: the exact plan before is the guess and its phases the sequence, its
    steps kept; a plan that failed gives no start, and without a chain before it the stage
    is misplaced."""
    import types

    from stand_in_plans import stand_in_plan

    from tfcontact.ocp.chain import ChainStep, ResolveChain
    from tfcontact.scenes.pipeline import NoStart, PreviousPlan

    plan = stand_in_plan("Solve_Succeeded", 1.0, shift=0.5)
    steps = (ChainStep.of("first", plan, 1.0),)

    def given(chain):
        before = PlanOutcome(None, None, "converged", True, "", chain=chain)
        return StageInput("p", "t", tmp_path, False, None, before)

    start = PreviousPlan().begin(given(ResolveChain(plan, None, steps, 0.0, 1.0)), ())
    assert start.guess[1] is plan.x and start.phases == plan.phases and start.steps == steps
    failed = stand_in_plan("Solve_Succeeded", 1.0, verification=types.SimpleNamespace(
        passed=False, summary=str))
    with pytest.raises(NoStart, match="the plan before is not verified \\(verification_failed"):
        PreviousPlan().begin(given(ResolveChain(failed, None, steps, 0.0, 1.0)), ())
    with pytest.raises(InvalidInput, match="goes on from an exact re-solve before it"):
        PreviousPlan().begin(given(None), ())


def test_the_stance_re_solve_keeps_the_lift_off_goals_heights():
    """A task's lift-off goals become the stance re-solve's swing heights (the goal's
    height and a margin over IPOPT's bound relaxation), per contact; none without them."""
    goals = [EndPosition("x", 0.2, 0.05), LiftOffs(1, 2, 0.05), LiftOffs(2, 1, 0.03)]
    assert lift_off_heights(goals, 3) == (None, 0.05 + LIFT_OFF_MARGIN,
                                          0.03 + LIFT_OFF_MARGIN)
    assert lift_off_heights(goals[:1], 3) == ()


def test_the_stance_re_solve_follows_a_discovery_stopped_short_only_within_its_residual(
        tmp_path):
    """A discovery whose homotopy stopped short (nlp_failed, not_converged) proposes its
    stances only with `StanceOptions.discovery_residual` set and its last solved NLP's
    complementarity residual within it; otherwise the stage does not start, keeps the
    discovery's outcome and says why (the option named). A converged discovery is always
    followed."""
    import math
    import types

    from tfcontact.ocp.stances import StanceOptions
    from tfcontact.scenes.pipeline import PlanSetup, StanceResolve, discovery_refusal

    def discovery(status, residual):
        return types.SimpleNamespace(status=status, ocp=types.SimpleNamespace(
            success=status == "converged", residual=residual))

    loose, tight = StanceOptions(discovery_residual=1e-2), StanceOptions(discovery_residual=1e-3)
    assert discovery_refusal(discovery("converged", 1e-4), StanceOptions()) is None
    assert discovery_refusal(discovery("nlp_failed", 3e-3), loose) is None
    assert discovery_refusal(discovery("not_converged", 1e-2), loose) is None
    assert "did not converge (nlp_failed); `discovery_residual` lets" in discovery_refusal(
        discovery("nlp_failed", 3e-3), StanceOptions())
    assert "residual 0.003 exceeds `discovery_residual` = 0.001" in discovery_refusal(
        discovery("nlp_failed", 3e-3), tight)
    assert discovery_refusal(discovery("nlp_failed", math.nan), loose) is not None
    for bad in (0.0, -1.0, math.inf, True, "0.01"):
        with pytest.raises(InvalidInput, match="`discovery_residual` must be None or"):
            StanceOptions(discovery_residual=bad)

    before = PlanOutcome("trajectory", None, "nlp_failed", False, "discovered",
                         result=discovery("nlp_failed", 3e-3),
                         setup=PlanSetup(None, None, None, {}))
    outcome = StanceResolve(tight).run(StageInput("p", "t", tmp_path, False, None, before))
    assert (outcome.status, outcome.success, outcome.trajectory) == (
        "nlp_failed", False, "trajectory")
    assert outcome.summary.startswith("discovered\nstance re-solve not started: the "
                                      "discovery's homotopy did not converge (nlp_failed)")


@pytest.mark.slow
def test_a_stance_re_solve_makes_a_verified_plan_from_a_discovery_cut_short(tmp_path):
    """The strider's discovery cut after two NLPs (sigma 1 and 0.1: not_converged, the
    relaxed plan 18 from the reference at T) proposes its stances, and the stance re-solve
    along them makes a plan that the multi-contact reference verifies and that does the
    task; the discovery's status stays in the summary (measured: both feet down, then
    a flight from 0.05 s; 41 IPOPT iterations)."""
    import dataclasses

    from strider import write_strider

    from tfcontact.scenes.plans import run_checked, task_plan

    discover, resolve = task_plan(str(write_strider(tmp_path))).stages

    def cut(task):
        setup = discover.build(task)
        options = setup.options
        return dataclasses.replace(setup, options=dataclasses.replace(
            options, attempts=1, homotopy=dataclasses.replace(options.homotopy, max_nlps=2)))

    stages = (Discover(cut), dataclasses.replace(resolve, options=dataclasses.replace(
        resolve.options, discovery_residual=0.2)))
    outcome, _, _, _ = run_checked("strider", "task", stages, tmp_path / "out")
    assert outcome.result is None  # the stance re-solve's outcome, not the discovery's
    assert outcome.summary.startswith("discovery: not_converged\nstances: converged")
    assert "verification PASSED" in outcome.summary and "task: done" in outcome.summary
    assert (outcome.status, outcome.success) == ("converged", True)
