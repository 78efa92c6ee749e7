"""The `tfcontact` command's plan listing and its errors (fast: nothing is solved)."""

import pytest

from tfcontact.cli import main
from tfcontact.errors import InvalidInput
from tfcontact.fesd import RadauIIA
from tfcontact.scenes import PLANS
from tfcontact.scenes.monoped import monoped_options


def test_plan_list_names_the_hopper(capsys):
    assert main(["plan", "--list"]) == 0
    out = capsys.readouterr().out
    assert "hopper" in out and "--task long" in out
    assert "monoped" in out and "--task reduced" in out and "exact re-solve" in out


def test_plan_list_starts_every_summary_in_one_column(capsys):
    """Names longer than the old fixed width (quadruped-jump-schedule) ran into their
    summaries; every summary now starts after the longest name."""
    from tfcontact.task import shipped_tasks

    assert main(["plan", "--list"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("  ")]
    names = [*PLANS, *shipped_tasks()]
    assert len(rows) == len(names)
    width = max(map(len, names))
    for row, name in zip(rows, names, strict=True):
        assert row.startswith(f"  {name} ") and row[2 + width] == " " and row[3 + width] != " "


def test_monoped_plan_is_tf9_from_the_urdf():
    """The CLI's monoped plan solves TF-9 from the URDF in three stages (the reduced hop
    discovered, re-solved exactly, tiled for the full task and re-solved): the full task by
    default, T = 2.5 s, N = 20, three elliptic holes, the ground lowered by the foot's
    radius in the sidecar's scene; `--task reduced` stops after the reduced hop."""
    from tfcontact.scenes.monoped import monoped_problem
    from tfcontact.scenes.monoped_exact import EXACT_TASK

    plan = PLANS["monoped"]
    assert plan.tasks == ("full", "reduced", "terrain", "hand-set")
    assert plan.build(None).problem.horizon == 1.0  # the discovery is the reduced task's
    assert [s.name for s in plan.stages_for("full")] == [
        "discover the reduced task's hop", "exact re-solve of the reduced hop",
        "exact re-solve of TF-9's task"]
    assert plan.stages_for("hand-set") == plan.stages_for("full")
    assert plan.stages_for("reduced") == plan.stages[:2]
    assert [s.name for s in plan.stages_for("terrain")][2] == (
        "exact re-solve of TF-9's task, holes as terrain")
    mp = monoped_problem(EXACT_TASK)
    assert mp.robot.nq == 4 and mp.problem.n_intervals == 20 and mp.problem.horizon == 2.5
    scene = mp.scene()
    assert [h["x_c"] for h in scene["holes"]] == [0.5, 1.5, 2.5]
    assert {h["form"] for h in scene["holes"]} == {"ellipse"}
    assert scene["terrain"]["height"] == pytest.approx(-0.028)
    assert monoped_options("full").scheme == RadauIIA(3)
    with pytest.raises(InvalidInput, match="unknown monoped task 'sprint'; tasks: full, reduced"):
        monoped_options("sprint")


def test_attempts_are_refused_for_a_plan_without_discovery(capsys, tmp_path, monkeypatch):
    from tfcontact.scenes import plans
    from tfcontact.scenes.pipeline import ExactResolve, Plan

    monkeypatch.setitem(plans.PLANS, "resolve", Plan("resolve", "re-solve only", ("only",),
                                                     (ExactResolve(),)))
    assert main(["plan", "resolve", "--attempts", "2", "--out", str(tmp_path), "--quiet"]) == 2
    assert "plan `resolve` has no discovery whose attempts could be set" in \
        capsys.readouterr().err


def test_unknown_plan_and_task_are_named(capsys, tmp_path):
    assert main(["plan", "walker", "--out", str(tmp_path)]) == 2
    assert "unknown plan `walker`; available: hopper, hopper-exact, monoped" in \
        capsys.readouterr().err
    assert main(["plan", "hopper", "--task", "sprint", "--out", str(tmp_path)]) == 2
    assert "plan `hopper` has no task `sprint`; tasks: short, long" in capsys.readouterr().err


def test_bad_attempts_are_refused_before_solving(capsys, tmp_path):
    out = tmp_path / "new"
    with pytest.raises(SystemExit) as exit_:
        main(["plan", "hopper", "--attempts", "0", "--out", str(out), "--quiet"])
    assert exit_.value.code == 2
    assert "--attempts must be a positive int, got '0'" in capsys.readouterr().err
    assert not out.exists()
