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
    assert "monoped" in out and "--task reduced" in out and "not solved yet" in out


def test_monoped_plan_builds_its_tasks():
    """The CLI's monoped plan is TF-9 from the URDF: the full task by default (3 stages,
    three holes in the sidecar's scene), the reduced one on request (2 stages, one hole)."""
    full = PLANS["monoped"].build(None)
    assert full.robot.nq == 4 and full.problem.n_intervals == 20
    assert full.problem.horizon == 2.5
    assert full.options.scheme == RadauIIA(3)
    assert [h["x_c"] for h in full.scene["holes"]] == [0.5, 1.5, 2.5]
    assert full.scene["terrain"]["height"] == pytest.approx(-0.028)
    reduced = PLANS["monoped"].build("reduced")
    assert reduced.problem.n_intervals == 10 and reduced.options.scheme == RadauIIA(2)
    assert [h["x_c"] for h in reduced.scene["holes"]] == [0.5]
    with pytest.raises(InvalidInput, match="unknown monoped task 'sprint'; tasks: full, reduced"):
        monoped_options("sprint")


def test_unknown_plan_and_task_are_named(capsys, tmp_path):
    assert main(["plan", "walker", "--out", str(tmp_path)]) == 2
    assert "unknown plan `walker`; available: hopper, monoped" in capsys.readouterr().err
    assert main(["plan", "hopper", "--task", "sprint", "--out", str(tmp_path)]) == 1
    assert "plan `hopper` has no task `sprint`; tasks: short, long" in capsys.readouterr().err


def test_bad_attempts_are_refused_before_solving(capsys, tmp_path):
    assert main(["plan", "hopper", "--attempts", "0", "--out", str(tmp_path), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "`attempts` must be a positive integer, got 0" in err
    assert not (tmp_path / "trajectory.npz").exists()
