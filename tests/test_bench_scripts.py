"""The hopper benchmark scripts' own logic, without their long solves.

`scripts/bench_hopper.py` replays nosnoc_py's plan with exact impacts (its controls
piecewise constant between the plan's clock values); `scripts/bench_hopper_settings.py`
changes one setting of `hopper_options()` per variant.
"""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest

from tfcontact.scenes.hopper import hopper_options, hopper_task
from tfcontact.scenes.particles import G, point_mass


def test_bench_replays_a_plan_against_its_end_state(load_script):
    """The bench's check of nosnoc_py's plan (`replay_controls` on the plan's clocks and
    controls, compared at T): a particle thrown sideways at 2 m/s from 1 m sticks where it
    lands (mu = 0.5); a 1 N push from the clock 0.5 s on is below mu m g."""
    bench = load_script("bench_hopper")
    cls = point_mass(2, mu=0.5, controlled=True)
    exact = np.array([2.0 * math.sqrt(2.0 / G), 0.0, 0.0, 0.0])
    args = (cls, np.array([0.0, 1.0, 2.0, 0.0]), np.array([0.0, 0.5, 1.0]),
            np.array([[0.0, 0.0], [1.0, 0.0]]), 1.0)
    assert bench.replay_deviation(*args, exact) < 1e-6
    wrong = exact + np.array([0.0, 0.0, 0.1, 0.0])
    assert bench.replay_deviation(*args, wrong) == pytest.approx(0.1, abs=1e-6)
    # the table's status for nosnoc_py's plan, which its own status does not check
    assert bench.replay_verdict(0.1, 5e-2) == "replay outside 0.05"
    assert bench.replay_verdict(1e-3, 5e-2) == "replay within 0.05"
    assert bench.replay_verdict(float("nan"), 5e-2) == "replay stopped"


def test_settings_variants_change_one_setting_each(load_script):
    settings = load_script("bench_hopper_settings")
    default = hopper_options("short")
    names = [f.name for f in fields(default)]
    for name, variant in settings.VARIANTS.items():
        options = variant(default)
        changed = [n for n in names if getattr(options, n) != getattr(default, n)]
        if name.startswith("default"):
            assert changed == [], name
        else:
            assert len(changed) == 1, (name, changed)
    task = hopper_task("short")
    task_names = [f.name for f in fields(task)]
    for name, variant in settings.TASK_VARIANTS.items():
        changed = [n for n in task_names if getattr(variant(task), n) != getattr(task, n)]
        assert len(changed) == 1, (name, changed)


def test_task_bench_tabulates_one_row_per_task_with_every_column(load_script):
    """`scripts/bench_tasks.py`'s table: a header of its columns, one row per measured
    task, times to 0.01 s, checks as written."""
    bench = load_script("bench_tasks")
    row = {column: f"<{column}>" for column in bench.COLUMNS}
    row.update({"solve [s]": 4.356, "verified": True})
    lines = bench.table([row, row]).splitlines()
    assert len(lines) == 4
    assert lines[0].count("|") == len(bench.COLUMNS) + 1
    assert "| 4.36 |" in lines[2] and "| True |" in lines[3]
    assert lines[2].split(" | ")[0] == "| <task>"


def test_legged_bench_tabulates_every_column(load_script):
    bench = load_script("bench_legged")
    row = {column: f"<{column}>" for column in bench.COLUMNS}
    row.update({"ms/iter eval": 55.041, "goals met": False})
    lines = bench.table([row]).splitlines()
    assert lines[0].count("|") == len(bench.COLUMNS) + 1
    assert "| 55.04 |" in lines[2] and lines[2].endswith("| False |")


def test_linear_solver_bench_changes_only_the_linear_algebra(load_script):
    """Each solver variant keeps the plan's own IPOPT settings (its options merged)."""
    from tfcontact.scenes.particle_ocps import box_circle_options

    bench = load_script("bench_linear_solvers")
    base = box_circle_options()
    for name, change in bench.SOLVERS.items():
        nlp = bench.with_solver(base, change).nlp
        assert nlp.tol == base.nlp.tol and nlp.max_iter == base.nlp.max_iter, name
        assert {k: v for k, v in nlp.options.items() if k in base.nlp.options} == \
            base.nlp.options, name
    assert bench.with_solver(base, bench.SOLVERS["spral"]).nlp.linear_solver == "spral"
    assert bench.with_solver(base, bench.SOLVERS["mumps METIS"]).nlp.options[
        "mumps_pivot_order"] == 5


def test_legged_bench_reports_a_whole_plan_stage_by_stage(load_script, monkeypatch):
    """`--whole`: each stage's seconds from summary.json go to their columns (a plan of two
    stages that only wait, without a trajectory to write)."""
    import time
    from dataclasses import dataclass

    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import Plan, PlanOutcome, Stage, StageInput

    @dataclass(frozen=True)
    class Wait(Stage):
        name: str
        pause: float
        tasks: tuple[str, ...] | None = None

        def run(self, given: StageInput) -> PlanOutcome:
            time.sleep(self.pause)
            return PlanOutcome(None, None, "converged", True, self.name)

    monkeypatch.setitem(plans.PLANS, "waits", Plan(
        "waits", "two waits", ("only",), (Wait("discover", 0.3), Wait("stance re-solve", 0.1))))
    bench = load_script("bench_legged")
    row = bench.measure_whole("waits")
    assert row["status"] == "converged"
    assert row["discover [s]"] >= 0.3 and row["re-solve [s]"] >= 0.1
    assert row["total [s]"] >= 0.4 and row["peak memory [GB]"] > 0
    assert 0 <= row["CPU [s]"] < 0.3  # the waits sleep: wall time, no CPU
    assert row["discovery iterations"] == "-" == row["re-solve iterations"]
    lines = bench.markdown_table(bench.WHOLE_COLUMNS, [row]).splitlines()
    assert lines[0].count("|") == len(bench.WHOLE_COLUMNS) + 1


def test_monoped_bench_tabulates_each_step_and_sets_its_route(load_script, monkeypatch):
    """`rows`: a plan's steps from its trajectory's chain steps (a discovery step without
    timings shows "-"); `child`: the "plain" route re-solves without element derivatives,
    the "element" route with the shipped ones."""
    import tfcontact.cli
    import tfcontact.scenes.monoped_exact as monoped_exact

    bench = load_script("bench_monoped")
    solver = {"objective": 176.43, "steps": [
        {"name": "time-freezing homotopy", "ipopt_status": "Solve_Succeeded",
         "iterations": 778, "seconds": 8.1, "objective": 50.9, "status": "failed",
         "timing": None, "peak_memory": None},
        {"name": "exact re-solve, 8 nodes", "ipopt_status": "Solve_Succeeded",
         "iterations": 458, "seconds": 41.7, "objective": 150.268, "status": "converged",
         "timing": {"build": 2.5, "evaluations": 20.25, "ipopt": 38.0, "n_variables": 1675,
                    "n_constraints": 1600},
         "peak_memory": 0.61}]}
    plan, steps = bench.rows("element", {"status": "converged"}, solver, 215.0, 0.7)
    assert plan["objective"] == 176.43 and plan["peak memory [GB]"] == 0.7
    assert steps[0]["build [s]"] == "-" and steps[0]["variables"] == "-"
    assert steps[0]["peak [GB]"] == "-"
    assert steps[1]["evaluations [s]"] == 20.25 and steps[1]["variables"] == 1675
    table = bench.markdown_table(bench.STEP_COLUMNS, steps).splitlines()
    assert "| 20.25 | 1675 | 0.61 | 150.268 | converged |" in table[3]
    # a step's peak above the child's maxrss (reset by the chain before each step) counts
    plan, _ = bench.rows("element", {"status": "converged"}, solver, 215.0, 0.5)
    assert plan["peak memory [GB]"] == 0.61

    seen = []
    monkeypatch.setattr(monoped_exact, "RESOLVE_DERIVATIVES", monoped_exact.RESOLVE_DERIVATIVES)
    monkeypatch.setattr(tfcontact.cli, "main", lambda argv: seen.append(
        (argv, monoped_exact.resolve_options(substeps=2).element_derivatives)) or 0)
    assert bench.child("element", "reduced", "out") == 0
    assert bench.child("plain", "reduced", "out") == 0
    assert [s[1] for s in seen] == [True, False]
    assert seen[0][0] == ["plan", "monoped", "--task", "reduced", "--out", "out", "--force"]


def test_curvature_parts_sum_to_ipopts_hessian_of_the_lagrangian(load_script):
    """`scripts/bench_discovery_curvature.py` on the hopper's vertical hop, its first NLP
    stopped after 5 iterations: the objective's, the FESD rows' and the Scholtes rows'
    Hessians, weighted by IPOPT's multipliers, add up to the Hessian of the Lagrangian
    that `MpccSolver` builds for IPOPT (upper triangle; its relaxed rows G H - sigma carry
    the Scholtes multipliers); the eigenvalue ranges on the null space of the equality
    rows obey Weyl's bounds for a sum, the tracking cost's Hessian is positive
    semidefinite, and the first rows (x(0) = x0) are labelled with the robot's
    coordinates in order."""
    import casadi as ca

    from tfcontact.mpcc import MpccSolver
    from tfcontact.task import load_task, shipped_tasks
    from tfcontact.task.build import build_task

    bench = load_script("bench_discovery_curvature")
    found = bench.curvature("hopper-vertical", 5)
    assert found.iterations == 5
    mpcc, w, p = found.point
    solver = MpccSolver(mpcc)
    hess_l = solver.nlp_function("nlp_hess_l")
    x = np.concatenate([w, np.zeros(hess_l.size1_in(0) - w.size)])
    lam = np.concatenate([found.lam_g, found.lam_c])
    ipopt = np.asarray(ca.DM(hess_l(x, np.append(p, found.sigma), 1.0, lam)))
    total = found.hessians["all"]
    assert np.abs(total).max() > 0
    np.testing.assert_allclose(np.triu(total), np.triu(ipopt)[: w.size, : w.size],
                               atol=1e-8 * np.abs(total).max())
    parts = [found.ranges[name] for name in found.ranges if name != "all"]
    low, high, _ = found.ranges["all"]
    scale = max(abs(low), abs(high))
    assert low >= sum(r[0] for r in parts) - 1e-9 * scale
    assert high <= sum(r[1] for r in parts) + 1e-9 * scale
    assert found.ranges["objective"][0] >= -1e-9 * found.ranges["objective"][1]
    q_names = build_task(load_task(shipped_tasks()["hopper-vertical"])).problem.system.cls.q_names
    assert found.row_states[:len(q_names)] == q_names
